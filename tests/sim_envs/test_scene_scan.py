"""Scenes, the MuJoCo camera and the SceneScan environment."""

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sim_envs  # noqa: F401  (registers the environments)
from conceptfusion.cameras import backproject, transform_points
from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.format import load_scene, save_scene
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.graph import object_aabbs

W, H = 160, 120


def test_env_passes_the_checker_and_runs_to_the_end():
    env = gym.make("cf/SceneScan-v0", num_frames=4, width=W, height=H)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=1)
    assert obs["rgb"].shape == (H, W, 3) and obs["depth"].dtype == np.float32
    assert info["segmentation"].shape == (H, W)
    steps, done = 0, False
    while not done:
        obs, reward, done, truncated, info = env.step(0)
        steps += 1
    assert steps == 3 and obs["frame"] == 3
    with pytest.raises(ValueError, match="Discrete"):
        env.unwrapped.step(5)
    env.close()


def test_same_seed_same_scene_and_frames():
    a = gym.make("cf/SceneScan-v0", num_frames=3, width=W, height=H)
    b = gym.make("cf/SceneScan-v0", num_frames=3, width=W, height=H)
    oa, ia = a.reset(seed=7)
    ob, ib = b.reset(seed=7)
    assert ia["object_names"] == ib["object_names"]
    assert np.array_equal(oa["rgb"], ob["rgb"]) and np.array_equal(oa["depth"], ob["depth"])
    oc, ic = a.reset(seed=8)
    assert ic["object_names"] != ia["object_names"]


def test_depth_and_segmentation_match_the_geometry():
    scene = generate_tabletop(3)
    sim = build_mujoco(scene)
    cam = MujocoRGBDCamera(sim.model, sim.data, 320, 240, geom_object=sim.geom_object)
    cam.set_pose((0.9, -0.9, 1.2), (0.0, 0.0, 0.4))
    f = cam.render()
    assert np.allclose(f.cam_to_world[:3, 3], [0.9, -0.9, 1.2], atol=1e-5)
    world = transform_points(f.cam_to_world, backproject(f.depth, f.K).reshape(-1, 3)).reshape(240, 320, 3)
    # the table top (a known surface) back-projects to its true height within 1 cm
    top = scene.table.top_z
    interior = (np.abs(world[..., 0]) < 0.58) & (np.abs(world[..., 1]) < 0.38)  # away from the side faces
    on_top = (f.segmentation < 0) & interior & (np.abs(world[..., 2] - top) < 0.05)
    assert on_top.sum() > 1000
    assert np.abs(world[on_top][:, 2] - top).max() < 0.01
    flat = (f.segmentation < 0) & (np.abs(world[..., 2] - top) < 0.002)
    assert np.abs(world[flat][:, :2]).max(axis=0) == pytest.approx([0.6, 0.4], abs=0.01)  # the table's edges
    boxes = object_aabbs(sim)
    for i, obj in enumerate(scene.objects):
        pts = world[f.segmentation == i]
        if len(pts) == 0:
            continue
        inside = np.all((pts >= boxes[i, 0] - 0.01) & (pts <= boxes[i, 1] + 0.01), axis=1)
        assert inside.mean() > 0.98, obj.name
    quick = cam.render(segmentation=False)  # one pass: same colour and depth, no ids
    assert np.array_equal(quick.rgb, f.rgb)
    finite = np.isfinite(f.depth)
    assert np.array_equal(np.isfinite(quick.depth), finite)
    assert np.abs(quick.depth[finite] - f.depth[finite]).max() < 1e-3
    assert (quick.segmentation == -1).all()
    cam.close()


def test_scene_file_round_trip_and_bad_files(tmp_path):
    scene = generate_tabletop(5)
    assert 4 <= len(scene.objects) <= 11
    path = save_scene(scene, tmp_path / "s.json")
    assert load_scene(path) == scene
    doc = json.loads(path.read_text())
    doc["objects"][0]["asset"] = "spaceship"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="unknown asset 'spaceship'"):
        load_scene(tmp_path / "bad.json")
    doc = json.loads(path.read_text())
    doc["objects"][1]["position"] = doc["objects"][0]["position"]
    (tmp_path / "overlap.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="overlap"):
        load_scene(tmp_path / "overlap.json")
    (tmp_path / "broken.json").write_text('{"format": "cf-scene", ')
    with pytest.raises(ValueError, match="malformed JSON at line 1"):
        load_scene(tmp_path / "broken.json")
    with pytest.raises(KeyError, match="no object 'nope'"):
        scene.object("nope")


def _frames_in_new_thread(fn):
    """``fn()`` run on a fresh thread (so in a GL context of its own under EGL)."""
    import threading

    out = {}
    t = threading.Thread(target=lambda: out.setdefault("v", fn()))
    t.start()
    t.join()
    return out["v"]


def test_cameras_sharing_the_threads_gl_context_render_what_lone_cameras_render():
    """Under EGL the cameras of a thread share one GL context: interleaving two scenes' cameras
    (and closing one before another is made) gives the pixels of cameras alone in a context."""
    poses = [((0.9, -0.9, 1.2), (0.0, 0.0, 0.4)), ((-0.7, 0.8, 1.0), (0.1, 0.0, 0.45))]

    def lone(seed, size):
        sim = build_mujoco(generate_tabletop(seed))
        cam = MujocoRGBDCamera(sim.model, sim.data, *size, geom_object=sim.geom_object)
        frames = []
        for eye, target in poses:
            cam.set_pose(eye, target)
            frames.append(cam.render())
        cam.close()
        return frames

    want = {(s, size): _frames_in_new_thread(lambda s=s, size=size: lone(s, size)) for s, size in ((3, (W, H)), (4, (96, 72)))}

    def shared():
        sims = {s: build_mujoco(generate_tabletop(s)) for s in (3, 4)}
        gone = MujocoRGBDCamera(sims[4].model, sims[4].data, 64, 48, geom_object=sims[4].geom_object)
        gone.render()
        gone.close()  # frees its renderer in the shared context, not the context
        cams = {3: MujocoRGBDCamera(sims[3].model, sims[3].data, W, H, geom_object=sims[3].geom_object),
                4: MujocoRGBDCamera(sims[4].model, sims[4].data, 96, 72, geom_object=sims[4].geom_object)}
        got = {3: [], 4: []}
        for eye, target in poses:
            for s in (3, 4):  # interleaved: each render must use its own camera's buffer
                cams[s].set_pose(eye, target)
                got[s].append(cams[s].render())
        return cams, got

    cams, got = _frames_in_new_thread(shared)
    import os
    if os.environ.get("MUJOCO_GL") == "egl":
        assert cams[3]._gl is cams[4]._gl and not cams[3]._owns_gl
    for s, size in ((3, (W, H)), (4, (96, 72))):
        for a, b in zip(want[(s, size)], got[s]):
            assert a.rgb.shape == (size[1], size[0], 3)
            assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth, b.depth)
            assert np.array_equal(a.segmentation, b.segmentation)
