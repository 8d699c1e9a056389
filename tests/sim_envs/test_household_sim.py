"""Household scenes in MuJoCo: settling, segmentation, scene graph, room sweeps, shipped files."""

import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim_envs  # noqa: F401  (registers the environments)
from scenes.make_scenes import SHIPPED_SEEDS, household_path, write_household_scenes
from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import build_mjcf, build_mujoco, split_labels
from sim_envs.scenes.format import load_scene
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.graph import furniture_aabbs, scene_graph
from sim_envs.envs.scene_scan import SceneScanEnv
from sim_envs.scenes.trajectories import room_sweep_trajectory

W, H = 160, 120


@pytest.fixture(scope="module")
def sim():
    return build_mujoco(generate_household(1))


def test_objects_rest_on_their_supports(sim):
    start = sim.data.xpos[sim.object_body].copy()
    for _ in range(400):
        mujoco.mj_step(sim.model, sim.data)
    moved = np.linalg.norm(sim.data.xpos[sim.object_body] - start, axis=1)
    assert moved.max() < 0.01, [sim.scene.objects[i].name for i in np.flatnonzero(moved >= 0.01)]
    graph = scene_graph(sim)  # support and containment read back from the settled state
    supported = dict(graph["supported_by"])
    assert all(supported.get(o.id) == o.support for o in sim.scene.objects), [(o.id, o.support, supported.get(o.id)) for o in sim.scene.objects]
    inside = set(graph["inside"])
    for o in sim.scene.objects:
        container = o.support if o.support.startswith("obj") else None
        if container is not None:
            assert (o.id, container) in inside
    assert any(b.startswith("f") for _, b in inside)  # something inside a cabinet or basket
    rooms = {r.id for r in sim.scene.rooms}
    assert all(ob["room"] in rooms for ob in graph["objects"])
    assert [f["id"] for f in graph["furniture"]] == [f.id for f in sim.scene.furniture]
    boxes = furniture_aabbs(sim)
    for j, f in enumerate(sim.scene.furniture):  # boxes match the declared sizes (90-degree yaws)
        lo, hi = f.footprint()
        assert np.allclose(boxes[j, 0, :2], lo, atol=0.01) and np.allclose(boxes[j, 1, :2], hi, atol=0.01), f.id
        assert boxes[j, 1, 2] == pytest.approx(f.size[2], abs=0.01)


def test_segmentation_reports_objects_and_furniture(sim):
    labels = sim.geom_labels()
    assert (sim.geom_furniture >= 0).sum() > 3 * len(sim.scene.furniture)
    assert np.all(sim.geom_object[sim.geom_furniture >= 0] == -1)
    cam = MujocoRGBDCamera(sim.model, sim.data, 320, 240, geom_object=labels)
    counts = [sum(o.support == f.id for o in sim.scene.objects) for f in sim.scene.furniture]
    j = int(np.argmax(counts))  # the piece carrying the most objects
    f = sim.scene.furniture[j]
    eye = f.to_world((0.0, -1.6))
    cam.set_pose((eye[0], eye[1], 1.3), (f.position[0], f.position[1], 0.5 * f.size[2]))
    frame = cam.render()
    cam.close()
    objects, furniture = split_labels(frame.segmentation, len(sim.scene.objects))
    assert (furniture == j).sum() > 2000  # the piece in front fills much of the view
    on_it = [i for i, o in enumerate(sim.scene.objects) if o.support == f.id]
    assert on_it and set(np.unique(objects[objects >= 0])) & set(on_it)
    assert ((objects >= 0) & (furniture >= 0)).sum() == 0


def test_labels_split_back():
    lab = np.array([[-1, 0, 3], [4, 6, 2]])
    o, f = split_labels(lab, 4)
    assert o.tolist() == [[-1, 0, 3], [-1, -1, 2]] and f.tolist() == [[-1, -1, -1], [0, 2, -1]]


def test_room_sweep_sees_most_objects_and_is_deterministic():
    scene = load_scene(household_path(0))
    env = SceneScanEnv(scene=scene, num_frames=6 * len(scene.rooms), width=W, height=H)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=0)
    first = obs["rgb"].copy()
    n = len(scene.objects)
    seen = np.zeros(n, int)
    furniture_seen = set()
    done = False
    while True:
        seen += np.bincount(info["segmentation"][info["segmentation"] >= 0], minlength=n)
        furniture_seen |= set(np.unique(info["furniture_segmentation"])) - {-1}
        if done:
            break
        obs, _, done, _, info = env.step(0)
        assert np.allclose(obs["cam_to_world"][2, 3], 1.3, atol=1e-4)
    assert (seen >= 5).mean() >= 0.8, [scene.objects[i].name for i in np.flatnonzero(seen < 5)]
    assert len(furniture_seen) >= 0.8 * len(scene.furniture)
    obs2, _ = SceneScanEnv(scene=load_scene(household_path(0)), num_frames=6 * len(scene.rooms), width=W, height=H).reset(seed=0)
    assert np.array_equal(obs2["rgb"], first)
    env.close()


def test_household_kind_generates_from_the_reset_seed():
    env = gym.make("cf/SceneScan-v0", kind="household", num_frames=8, width=W, height=H)
    oa, a = env.reset(seed=3)
    ob, b = env.reset(seed=3)
    _, c = env.reset(seed=4)
    assert np.array_equal(oa["rgb"], ob["rgb"]) and np.array_equal(oa["depth"], ob["depth"])
    assert a["scene_id"].startswith("household-") and a["object_names"] == b["object_names"] != c["object_names"]
    assert a["scene_graph"]["rooms"] and a["furniture_ids"]
    env.close()
    with pytest.raises(ValueError, match="kind: expected one of .*'houshold'.*did you mean 'household'"):
        SceneScanEnv(kind="houshold")


def test_sweep_spreads_frames_over_rooms():
    scene = generate_household(2)
    traj = room_sweep_trajectory(scene, 2 * len(scene.rooms) + 1)
    eyes = [tuple(np.round(e[:2], 6)) for e, _ in traj]
    assert [eyes.count(tuple(np.round(r.center, 6))) for r in scene.rooms] == [3] + [2] * (len(scene.rooms) - 1)
    assert all(t[2] < e[2] for e, t in traj)  # looking down
    with pytest.raises(ValueError, match="at least one frame per room"):
        room_sweep_trajectory(scene, 2)


def test_shipped_scenes_match_the_generator(tmp_path):
    for seed in SHIPPED_SEEDS:
        assert load_scene(household_path(seed)) == generate_household(seed), seed
    written = write_household_scenes([0], tmp_path)
    assert written[0].read_text() == household_path(0).read_text()


def test_household_mjcf_has_textured_walls_floors_and_furniture():
    scene = generate_household(0)
    xml = build_mjcf(scene)
    assert xml.count("<texture") >= 10 and "castshadow=\"true\"" not in xml
    assert 'offsamples="0"' in xml
    for r in scene.rooms:
        assert f'name="{r.id}_floor"' in xml and f"hm_{r.floor_material}" in xml
    assert all(f'<body name="{f.id}"' in xml for f in scene.furniture)
    assert json.loads(json.dumps(scene.to_json()))["kind"] == "household"


def test_overview_picture_is_textured_and_needs_rooms():
    from scenes.make_scenes import render_overview
    from sim_envs.scenes.gen_tabletop import generate_tabletop

    rgb = render_overview(generate_household(0), 160, 120)
    assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
    assert len(np.unique(rgb.reshape(-1, 3), axis=0)) > 200  # textured, not flat
    with pytest.raises(ValueError, match="needs rooms"):
        render_overview(generate_tabletop(0))
