"""The PyBullet tabletop backend: Franka Panda pushes, refusals, determinism, rendering."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_envs.scenes.format import Scene, SceneObject, Table
from sim_envs.envs.tabletop_sim import PUSH_HEIGHT

pytest.importorskip("pybullet")
from sim_envs.pybullet.tabletop import PyBulletTabletop  # noqa: E402

TABLE = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))
TOP = TABLE.top_z


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CF_ASSET_CACHE", str(tmp_path_factory.mktemp("assets")))
        yield


def push_scene() -> Scene:
    """A low box (below the hand) across the push line at the table centre, a can far away."""
    objects = (
        SceneObject("obj0", "red box", "box", "box", "red", (0.0, 0.0, TOP), 0.0, (0.10, 0.08, 0.03)),
        SceneObject("obj1", "blue can", "can", "can", "blue", (0.4, 0.2, TOP), 0.0, (0.066, 0.066, 0.12)),
    )
    return Scene("push-test", "tabletop", 0, TABLE, objects, ((0.0, -0.4), (0.0, 0.4)))


@pytest.fixture()
def sim():
    s = PyBulletTabletop(push_scene(), seed=0, renderer="tiny")
    yield s
    s.close()


def test_initial_poses_and_boxes_follow_the_scene(sim):
    poses = sim.object_poses()
    assert poses.shape == (2, 7)
    assert np.allclose(poses[:, :3], [o.position for o in sim.scene.objects], atol=2e-3)
    assert np.allclose(np.linalg.norm(poses[:, 3:], axis=1), 1.0)
    boxes = sim.object_aabbs()
    assert boxes.shape == (2, 2, 3)
    assert np.allclose(boxes[0, 1] - boxes[0, 0], [0.10, 0.08, 0.03], atol=3e-3)


def test_push_moves_the_box_by_the_pushed_distance_and_leaves_the_far_object(sim):
    before = sim.object_poses()
    gap, distance = 0.03, 0.15  # fingertip starts 3 cm before the box's near face (y = -0.04)
    out = sim.push((0.0, -0.04 - gap), math.pi / 2, distance)
    after = sim.object_poses()
    assert out.executed and out.reason == "" and out.contact
    moved = after[0, :3] - before[0, :3]
    # The box travels the push minus the gap, plus about the finger's half thickness.
    assert moved[1] == pytest.approx(distance - gap, abs=0.03)
    assert abs(moved[0]) < 0.02 and abs(moved[2]) < 0.005
    assert np.linalg.norm(after[1, :3] - before[1, :3]) < 0.005
    path = out.fingertip_path
    assert path.ndim == 2 and path.shape[1] == 3
    low = path[:, 2] < TOP + 0.05
    assert path[low, 1].max() == pytest.approx(-0.04 - gap + distance, abs=0.01)
    along = low & (path[:, 1] > -0.04 - gap + 0.02) & (path[:, 1] < -0.04 - gap + distance - 0.02)
    assert along.sum() > 10
    assert np.all(np.abs(path[along, 2] - (TOP + PUSH_HEIGHT)) < 0.005)  # pushes at PUSH_HEIGHT


def test_unreachable_push_is_refused_and_nothing_moves(sim):
    before = sim.object_poses()
    out = sim.push((0.55, 0.38), 0.0, 0.1)  # the far corner, out of the arm's reach
    assert not out.executed and out.reason.startswith("the arm cannot reach")
    assert out.fingertip_path.shape == (0, 3) and not out.contact
    assert np.array_equal(sim.object_poses(), before)
    assert not sim.can_reach((0.55, 0.38)) and sim.can_reach((0.0, 0.0))


def test_push_starting_over_an_object_is_refused(sim):
    out = sim.push((0.4, 0.2), 0.0, 0.1)
    assert not out.executed and "lies over object 'obj1'" in out.reason


def test_same_seed_same_pushes_same_final_poses():
    finals = []
    for _ in range(2):
        s = PyBulletTabletop(push_scene(), seed=3, renderer="tiny")
        s.push((-0.02, -0.1), math.pi / 2 + 0.2, 0.12)
        finals.append(s.object_poses())
        s.close()
    assert np.array_equal(finals[0], finals[1])
    assert np.linalg.norm(finals[0][0, :2]) > 0.02  # the push did something


def test_render_labels_objects_and_not_the_arm(sim):
    frame = sim.render((0.0, -0.9, 1.2), (0.0, 0.0, 0.4), 160, 120)
    labels = set(np.unique(frame.segmentation).tolist())
    assert labels == {-1, 0, 1}
    assert np.isfinite(frame.depth).mean() > 0.9


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="expected a tabletop scene with a table"):
        PyBulletTabletop(Scene("x", "tabletop", 0, None, ()))
    with pytest.raises(ValueError, match="renderer: expected one of"):
        PyBulletTabletop(push_scene(), renderer="opengl")


def test_bad_push_arguments_are_named(sim):
    with pytest.raises(ValueError, match="start_xy: expected 2 finite numbers"):
        sim.push((0.0, 0.0, 0.0), 0.0, 0.1)
    with pytest.raises(ValueError, match="distance >= 0"):
        sim.push((0.0, -0.2), 0.0, -0.1)


def test_transit_moves_are_planned_collision_free_with_ompl(sim):
    from sim_envs.pybullet.tabletop import HOME_JOINTS

    sim._place_obstacles()
    assert sim.kin.config_free(np.array(HOME_JOINTS))
    # the fingertip on the table top is not free (the hand is inside the clearance)
    low, err = sim.kin.reach(np.array([0.0, 0.1, TOP + 0.002]), np.array(HOME_JOINTS))
    assert err < 0.02 and not sim.kin.config_free(low)
    # the tip inside the can's box is not free either
    inside, err = sim.kin.reach(np.array([0.4, 0.2, TOP + 0.06]), np.array(HOME_JOINTS))
    assert err < 0.02 and not sim.kin.config_free(inside)
    above, _ = sim.kin.reach(np.array([0.4, 0.2, TOP + 0.35]), np.array(HOME_JOINTS))
    path, why = sim.kin.plan_transit(np.array(HOME_JOINTS), above, "above the can")
    assert path is not None, why
    assert np.allclose(path[0], HOME_JOINTS) and np.allclose(path[-1], above)
    dense = [a + (b - a) * t for a, b in zip(path[:-1], path[1:]) for t in np.linspace(0, 1, 8)]
    assert all(sim.kin.config_free(q) for q in dense)
    blocked, why = sim.kin.plan_transit(np.array(HOME_JOINTS), inside, "inside the can")
    assert blocked is None and "no collision-free arm motion to inside the can" in why
