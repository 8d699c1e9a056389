"""cf/TabletopRearrange-v0: checker, determinism, action handling, success judging, vectorising."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim_envs  # noqa: F401  (registers the environments)
from sim_envs.scenes.episodes import Episode, Goal
from sim_envs.envs.rearrange_eval import evaluate, signed_line_distance
from sim_envs.scenes.format import Scene, SceneObject
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.mujoco.tabletop import MujocoTabletop
from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv, make_backend

W, H = 64, 48


def _env(**kw):
    return TabletopRearrangeEnv(width=W, height=H, **kw)


def _two_object_scene() -> Scene:
    base = generate_tabletop(0)
    a = SceneObject("obj0", "red can", "can", "can", "red", (-0.2, 0.0, base.table.top_z), 0.0, (0.066, 0.066, 0.12))
    b = SceneObject("obj1", "blue box", "box", "box", "blue", (0.25, 0.2, base.table.top_z), 0.0, (0.1, 0.08, 0.08))
    return Scene("two", "tabletop", 0, base.table, (a, b), base.line)


def test_env_passes_the_checker():
    env = gym.make("cf/TabletopRearrange-v0", width=W, height=H)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=2)
    assert obs["rgb"].shape == (H, W, 3) and obs["depth"].shape == (H, W)
    assert obs["instruction"].startswith("push the ") and "of the line" in obs["instruction"]
    assert set(obs) == {"rgb", "depth", "K", "cam_to_world", "instruction", "line"}  # no ground truth
    assert 1 <= len(info["target_ids"]) <= 2 and not info["success"]
    env.close()


def test_targets_start_on_the_other_side():
    env = _env()
    for seed in range(4):
        _, info = env.reset(seed=seed)
        scene = env.sim.scene
        for oid, side in zip(info["target_ids"], info["target_sides"]):
            d = signed_line_distance(scene, [scene.object(oid).position[:2]])[0]
            assert (d < 0) == (side == "right")
    env.close()


def test_same_seed_same_scene_frame_and_outcome():
    action = np.array([-0.3, 0.0, 0.0, 0.3, 0.0], np.float32)
    runs = []
    for _ in range(2):
        env = _env()
        obs, info = env.reset(seed=5)
        obs2, _, _, _, info2 = env.step(action)
        runs.append((info["object_names"], obs["rgb"], info2["object_poses"], obs2["depth"]))
        env.close()
    (n1, rgb1, p1, d1), (n2, rgb2, p2, d2) = runs
    assert n1 == n2 and np.array_equal(rgb1, rgb2) and np.array_equal(p1, p2) and np.array_equal(d1, d2)
    env = _env()
    _, other = env.reset(seed=6)
    assert other["object_names"] != n1


def test_out_of_bounds_actions_are_clipped_and_nan_raises():
    env = _env()
    env.reset(seed=1)
    _, _, _, _, info = env.step(np.array([5.0, -9.0, 7.0, 3.0, 0.0]))
    push = info["last_push"]
    assert np.allclose(push["start_xy"], [0.6, -0.4]) and np.isclose(push["distance"], 0.5) and push["clipped"]
    assert -np.pi <= push["direction_rad"] < np.pi and abs(push["direction_rad"] - (7.0 - 2 * np.pi)) < 1e-6
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, np.nan, 0.0, 0.1, 0.0]))
    with pytest.raises(ValueError, match=r"shape \(5,\)"):
        env.step(np.zeros(4))
    env.close()


def test_stop_ends_and_max_steps_truncates():
    env = _env(max_steps=2)
    env.reset(seed=3)
    _, r, term, trunc, info = env.step(np.array([0, 0, 0, 0, 1.0]))
    assert term and not trunc and r == 0.0 and info["last_push"] == {"stop": True}
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(5))
    env.reset(seed=3)
    _, _, term, trunc, _ = env.step(np.array([0.59, 0.39, 0, 0.01, 0]))
    assert not term and not trunc
    _, _, term, trunc, _ = env.step(np.array([0.59, 0.39, 0, 0.01, 0]))
    assert trunc and not term
    env.close()


def test_success_judged_from_hand_placed_states():
    scene = _two_object_scene()
    ep = Episode("hand", "two", 0, "push the red can to the right of the line", (Goal("obj0", "right"),), None, 6)
    env = _env(scene=scene)
    env.reset(seed=0, options={"episode": ep})
    sim = env.sim
    stop = np.array([0, 0, 0, 0, 1.0])
    sim.set_object_pose(0, (0.015, 0.0, 0.4))  # only 1.5 cm past the line: not yet
    assert not env.evaluate().success
    sim.set_object_pose(0, (0.03, 0.0, 0.4))  # 3 cm past: done
    assert env.evaluate().success
    sim.set_object_pose(1, (0.25, 0.26, 0.4))  # the distractor moved 6 cm: fails
    res = env.evaluate()
    assert not res.success and res.targets_done == (True,) and not res.distractors_still
    sim.set_object_pose(1, (0.25, 0.24, 0.4))  # 4 cm: tolerated
    _, reward, term, _, info = env.step(stop)
    assert term and reward == 1.0 and info["success"]
    env.close()


def test_evaluate_pure_function_checks_inputs():
    scene = _two_object_scene()
    poses = np.zeros((2, 7)); poses[:, 3] = 1.0
    with pytest.raises(ValueError, match="expected \\(2, 7\\)"):
        evaluate(scene, poses, poses[:1], [("obj0", "right")])
    with pytest.raises(ValueError, match="obj9"):
        evaluate(scene, poses, poses, [("obj9", "right")])


def test_push_backend_refuses_bad_start_points_and_pushes():
    sim = MujocoTabletop(_two_object_scene())
    before = sim.object_poses()
    out = sim.push((-0.2, 0.0), 0.0, 0.1)  # inside the can
    assert not out.executed and "obj0" in out.reason
    out = sim.push((0.7, 0.0), 0.0, 0.1)
    assert not out.executed and "off the table" in out.reason
    assert np.array_equal(sim.object_poses(), before)
    out = sim.push((-0.3, 0.0), 0.0, 0.15)  # 5 cm of approach, then 10 cm of pushing
    moved = sim.object_poses()[0, :2] - before[0, :2]
    assert out.executed and out.contact and 0.04 < moved[0] < 0.12
    assert np.linalg.norm(sim.object_poses()[1, :2] - before[1, :2]) < 1e-3
    sim.close()


def test_resting_objects_sleep_and_what_the_fingertip_touches_wakes():
    """Objects at rest sleep (MuJoCo island sleeping): a push far from the box leaves it exactly
    where it was, the can it meets wakes and moves; the fingertip never sleeps; a pose written by
    hand wakes its object and shows at once in the object's box."""
    import mujoco

    sim = MujocoTabletop(_two_object_scene())
    model, data = sim.model, sim.data
    assert model.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    trees = [int(model.body_treeid[b]) for b in sim.mj.object_body]
    finger_tree = int(model.body_treeid[model.geom_bodyid[sim._finger_geom]])
    assert model.tree_sleep_policy[finger_tree] == int(mujoco.mjtSleepPolicy.mjSLEEP_NEVER)
    out = sim.push((-0.1, -0.35), 0.0, 0.1)  # through empty table: physics runs, nothing is touched
    assert out.executed and not out.contact
    assert all(data.tree_asleep[t] >= 0 for t in trees), data.tree_asleep
    before = sim.object_poses()
    out = sim.push((-0.3, 0.0), 0.0, 0.15)
    after = sim.object_poses()
    assert out.executed and out.contact and 0.04 < after[0, 0] - before[0, 0] < 0.12
    assert np.array_equal(after[1], before[1])  # asleep throughout: not a bit of drift
    box = sim.object_aabbs()[1].copy()
    sim.set_object_pose(1, before[1, :3] + np.array([0.05, 0.0, 0.0]))
    assert data.tree_asleep[trees[1]] < 0  # awake
    assert np.allclose(sim.object_aabbs()[1], box + np.array([0.05, 0.0, 0.0]), atol=1e-9)
    sim.close()


def test_scan_returns_posed_orbit_frames():
    env = _env()
    env.reset(seed=0)
    frames = env.unwrapped.scan(3, segmentation=True)
    assert len(frames) == 3 and frames[0].rgb.shape == (H, W, 3)
    assert not np.allclose(frames[0].cam_to_world, frames[1].cam_to_world)
    assert (frames[0].segmentation >= 0).any()
    env.close()


def test_unknown_backend_names_the_valid_ones():
    with pytest.raises(ValueError, match="did you mean 'mujoco'"):
        TabletopRearrangeEnv(backend="mujocoo")
    with pytest.raises(ValueError, match="expected one of"):
        make_backend("gazebo", _two_object_scene())


def test_vector_env_runs_a_few_steps():
    # spawn: earlier tests hold GL contexts in this process, which a forked worker must not inherit
    envs = gym.vector.AsyncVectorEnv(
        [lambda: TabletopRearrangeEnv(width=W, height=H) for _ in range(2)], shared_memory=False, context="spawn"
    )
    obs, _ = envs.reset(seed=[0, 1])
    assert obs["rgb"].shape == (2, H, W, 3)
    for _ in range(2):
        obs, rew, term, trunc, _ = envs.step(np.tile(np.array([0.5, 0.3, 0.0, 0.05, 0.0], np.float32), (2, 1)))
    assert rew.shape == (2,) and not term.any()
    envs.close()


def test_pybullet_backend_is_selected_by_name():
    pytest.importorskip("sim_envs.pybullet.tabletop", reason="the PyBullet backend is not installed")
    env = TabletopRearrangeEnv(backend="pybullet", width=W, height=H)
    obs, info = env.reset(seed=1)
    assert type(env.sim).__name__ == "PyBulletTabletop" and obs["rgb"].shape == (H, W, 3)
    _, _, _, _, info = env.step(np.array([0.59, 0.39, 0.0, 0.01, 0.0], np.float32))
    assert "executed" in info["last_push"] and info["success"] is False
    env.close()


def test_without_segmentation_the_observations_are_the_same_and_info_has_none():
    obs = {}
    for seg in (True, False):
        env = _env(scan_frames=2, segmentation=seg)
        o, info = env.reset(seed=3)
        o, *_, info = env.step(np.array([0.0, 0.0, 0.3, 0.1, 0.0]))
        assert ("segmentation" in info) == seg and ("scan_segmentation" in info) == seg
        obs[seg] = o
        env.close()
    for key in ("rgb", "depth", "scan_rgb", "scan_depth", "scan_cam_to_world"):
        assert np.array_equal(obs[True][key], obs[False][key], equal_nan=True), key
    with pytest.raises(TypeError, match="segmentation: expected True or False"):
        _env(segmentation="no")
