"""Households in PyBullet: the same apartment as in MuJoCo (depth, segment ids), the search and
scan environments on both backends, and the assets PyBullet cannot load refused before an episode."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from conceptfusion.errors import SceneFormatError, UnknownNameError
from sim_envs.envs.household_backends import HouseholdBackend
from sim_envs.envs.object_search import ObjectSearchEnv
from sim_envs.envs.scene_scan import SceneScanEnv
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes
from sim_envs.scenes.format import load_scene

p = pytest.importorskip("pybullet")

V1 = SCENES_ROOT / "household" / "household-0000.json"
V2 = SCENES_ROOT / "household-v2" / "household-v2-300000.json"
MIN_PIXELS = 30
MIN_IOU = 0.8


def _views(scene):
    """Four views per room from its centre: camera at 1.2 m, 20 degrees down, facing +x, +y, -x, -y."""
    for r in scene.rooms:
        cx, cy = r.center
        for k in range(4):
            yaw, pitch = k * math.pi / 2, math.radians(20)
            eye = (cx, cy, 1.2)
            yield eye, (cx + math.cos(yaw) * math.cos(pitch), cy + math.sin(yaw) * math.cos(pitch), 1.2 - math.sin(pitch))


@pytest.mark.parametrize("path", [V1, V2], ids=["v1", "v2"])
def test_same_apartment_same_pose_same_depth_and_segments(path):
    """Both simulators render one shipped apartment from the same poses (four per room).

    Walls and floors (pixels both label -1 and both hit) must agree in depth to a median under
    2 cm (measured: about 1 mm; a wall misplaced by a wall's thickness would be 10 cm off). Every
    segment id seen on at least 30 pixels in either image must be the same object or piece of
    furniture in both: IoU at least 0.8. Measured: median IoU 1.0, worst 0.94 (a 30-pixel v1
    procedural mug whose round sides the two rasterisers tessellate differently); an id mapped to
    the wrong object gives an IoU near 0, and a one-pixel shift of a 30-pixel blob about 0.7.
    """
    scene = load_scene(path)
    n = len(scene.objects)
    backends = {b: HouseholdBackend(b, scene, camera=(160, 120, 70.0), labels="objects+furniture") for b in ("mujoco", "pybullet")}
    if backends["pybullet"].camera.renderer != "egl":
        pytest.skip("PyBullet's EGL plugin did not load; the tiny renderer samples pixels elsewhere (see its K)")
    try:
        seen = set()
        for eye, target in _views(scene):
            frames = {}
            for b, be in backends.items():
                be.camera.set_pose(eye, target)
                frames[b] = be.camera.render()
            m, q = frames["mujoco"], frames["pybullet"]
            np.testing.assert_allclose(q.K, m.K, atol=1e-9)
            np.testing.assert_allclose(q.cam_to_world, m.cam_to_world, atol=1e-5)
            room = (m.segmentation == -1) & (q.segmentation == -1) & np.isfinite(m.depth) & np.isfinite(q.depth)
            assert room.sum() > 0.3 * room.size
            assert float(np.median(np.abs(m.depth[room] - q.depth[room]))) < 0.02
            for label in set(np.unique(m.segmentation)) | set(np.unique(q.segmentation)):
                a, b = m.segmentation == label, q.segmentation == label
                if label < 0 or max(a.sum(), b.sum()) < MIN_PIXELS:
                    continue
                iou = (a & b).sum() / (a | b).sum()
                what = scene.objects[label].id if label < n else scene.furniture[label - n].id
                assert iou >= MIN_IOU, f"{path.name} {what}: IoU {iou:.2f} from eye {eye}"
                seen.add(int(label))
        assert any(s < n for s in seen) and any(s >= n for s in seen)  # objects and furniture both compared
    finally:
        for be in backends.values():
            be.close()


@pytest.mark.parametrize("folder", ["household", "household-v2"])
def test_every_object_and_piece_of_the_shipped_apartments_loads(folder):
    """Every scene of the folder builds in PyBullet: one body per object, resting where the scene
    puts it, with collision geometry; every piece of furniture has bodies."""
    for path in sorted((SCENES_ROOT / folder).glob("household*.json")):
        scene = load_scene(path)
        be = HouseholdBackend("pybullet", scene, camera=None)
        try:
            sim, client = be.sim, be._client
            assert len(sim.object_body) == len(scene.objects)
            assert sorted(set(sim.body_furniture.values())) == list(range(len(scene.furniture)))
            boxes = sim.object_aabbs()
            for i, (o, b) in enumerate(zip(scene.objects, sim.object_body)):
                assert p.getCollisionShapeData(int(b), -1, physicsClientId=client), f"{path.name} {o.id}: no collision shape"
                assert boxes[i, 0, 2] == pytest.approx(o.position[2] + 0.001, abs=1e-4)
                np.testing.assert_allclose((boxes[i, 0, :2] + boxes[i, 1, :2]) / 2, o.position[:2], atol=1e-4)
        finally:
            be.close()


@pytest.fixture(scope="module")
def v2_episodes():
    return load_episodes(SCENES_ROOT / "household-v2" / "episodes-v2.jsonl").episodes


def test_search_moves_and_scores_the_same_on_both_backends(v2_episodes):
    """One action sequence (drive, turn, drive into whatever is ahead, stop) gives the same poses,
    collisions and outcome on both backends; goal boxes agree within the 2 cm the docstring allows."""
    ep = v2_episodes[0]
    actions = [np.array([0.6, 0.0, 0.0], np.float32)] * 6 + [np.array([0.0, 1.5, 0.0], np.float32)] * 2
    actions += [np.array([0.6, 0.3, 0.0], np.float32)] * 12 + [np.array([0.0, 0.0, 1.0], np.float32)]
    runs = {}
    for backend in ("mujoco", "pybullet"):
        env = ObjectSearchEnv(width=64, height=48, backend=backend)
        try:
            obs, info = env.reset(seed=0, options={"episode": ep})
            poses, goal_box = [obs["base_pose"].copy()], info["goal_aabb"]
            for a in actions:
                obs, _, term, trunc, info = env.step(a)
                poses.append(obs["base_pose"].copy())
                assert obs["depth"].shape == (48, 64) and np.isfinite(obs["depth"]).mean() > 0.9
                if term or trunc:
                    break
            runs[backend] = (np.array(poses), info, goal_box)
        finally:
            env.close()
    (pm, im, bm), (pp, ip, bp) = runs["mujoco"], runs["pybullet"]
    np.testing.assert_array_equal(pm, pp)
    for key in ("collisions", "steps", "success", "path_length", "shortest_path_length"):
        assert im[key] == ip[key], key
    assert np.abs(bm - bp).max() < 0.025
    assert im["distance_to_goal"] == pytest.approx(ip["distance_to_goal"], abs=0.025)


def test_scan_labels_objects_and_furniture_alike():
    """A PyBullet household scan labels the same objects and furniture as MuJoCo's and builds the
    same scene graph relations, up to the looser boxes MuJoCo gives library meshes."""
    scene = load_scene(V2)
    out = {}
    for backend in ("mujoco", "pybullet"):
        env = SceneScanEnv(scene=scene, kind="household", num_frames=4, width=80, height=60, backend=backend)
        try:
            obs, info = env.reset(seed=0)
            out[backend] = (info, obs)
        finally:
            env.close()
    (im, om), (ip, op) = out["mujoco"], out["pybullet"]
    assert im["object_ids"] == ip["object_ids"] and im["furniture_ids"] == ip["furniture_ids"]
    for key in ("segmentation", "furniture_segmentation"):
        agree = (im[key] == ip[key]).mean()
        assert agree > 0.97, f"{key}: {agree:.3f} of pixels agree"
    assert (ip["furniture_segmentation"] >= 0).any()
    # MuJoCo boxes a library mesh in its principal axes, a box up to 1.4 cm deeper than the
    # object, so it misses a few supports the scene declares; PyBullet's boxes are the objects'
    # sizes. Every relation MuJoCo finds PyBullet finds, and each one it adds is the declared one.
    sm, sp = set(im["scene_graph"]["supported_by"]), set(ip["scene_graph"]["supported_by"])
    assert sm <= sp
    declared = {(o.id, o.support) for o in scene.objects}
    assert sp - sm <= declared
    assert set(im["scene_graph"]["inside"]) == set(ip["scene_graph"]["inside"])
    np.testing.assert_allclose(op["cam_to_world"], om["cam_to_world"], atol=1e-5)


@pytest.mark.parametrize("cls", [ObjectSearchEnv, SceneScanEnv])
def test_unknown_backend_is_refused_naming_the_field_and_choices(cls):
    with pytest.raises(UnknownNameError, match=r"backend: expected one of \['mujoco', 'pybullet'\], got 'pybulet'.*'pybullet'"):
        cls(backend="pybulet")
    with pytest.raises(UnknownNameError, match=r"backend: expected one of .*got 3"):
        cls(backend=3)


# -- assets PyBullet cannot load -------------------------------------------------------------


def _scene_with_first_object_hull(monkeypatch, tmp_path, text: str, which: str = "hull"):
    """The v2 apartment, with its first object's first collision piece (or visual mesh) replaced
    by a file holding ``text``; returns (scene, bad file, object asset)."""
    import sim_envs.assets.library.export as export

    scene = load_scene(V2)
    asset = scene.objects[0].asset
    real = export.export_instance(asset)
    bad = tmp_path / f"bad_{which}.obj"
    bad.write_text(text)
    broken = (dataclasses.replace(real, hulls=(bad, *real.hulls[1:])) if which == "hull"
              else dataclasses.replace(real, visual=bad))
    original = export.export_instance

    def fake(instance):
        inst = export.get_instance(instance) if isinstance(instance, str) else instance
        return broken if inst.id == real.instance.id else original(instance)

    monkeypatch.setattr(export, "export_instance", fake)
    return scene, bad, asset


FLAT = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"


@pytest.mark.parametrize("text, which, why", [
    ("v 0 0 zero\nf 1 2 3\n", "hull", "not a readable OBJ mesh"),
    (FLAT, "hull", "a collision piece with zero volume"),
    ("# nothing here\n", "visual", "no geometry"),
])
def test_a_mesh_pybullet_cannot_load_is_refused_with_field_and_file(monkeypatch, tmp_path, text, which, why):
    scene, bad, asset = _scene_with_first_object_hull(monkeypatch, tmp_path, text, which)
    client = p.connect(p.DIRECT)
    try:
        from sim_envs.pybullet.scene import build_pybullet

        with pytest.raises(SceneFormatError, match=rf"household-v2-300000\.json: objects\[0\]\.asset .*{asset}.*{bad.name}: {why}"):
            build_pybullet(scene, client, source=str(V2))
        assert p.getNumBodies(physicsClientId=client) == 0  # refused before anything loaded
    finally:
        p.disconnect(client)


def test_search_refuses_a_broken_mesh_at_reset_before_the_episode(monkeypatch, tmp_path, v2_episodes):
    scene, bad, _ = _scene_with_first_object_hull(monkeypatch, tmp_path, FLAT)
    ep = next(e for e in v2_episodes if Path(e.scene).name == V2.name)
    env = ObjectSearchEnv(width=64, height=48, backend="pybullet")
    try:
        with pytest.raises(SceneFormatError, match=rf"household-v2/household-v2-300000\.json: objects\[0\]\.asset.*{bad.name}.*zero volume"):
            env.reset(options={"episode": ep})
        with pytest.raises(Exception, match="reset"):  # no episode started
            env.step(np.zeros(3, np.float32))
    finally:
        env.close()


def test_a_primitive_without_volume_is_refused_naming_where():
    from sim_envs.pybullet.shapes import mjcf_shapes

    with pytest.raises(ValueError, match=r"furniture\[2\] \('f2'\): geom 1 \(box\) has no volume: size '0.2 0 0.1'"):
        mjcf_shapes('<geom type="box" size="0.1 0.1 0.1"/><geom type="box" size="0.2 0 0.1"/>', "furniture[2] ('f2')")
    with pytest.raises(ValueError, match=r"geom 0 \(cylinder\) has no volume"):
        mjcf_shapes('<geom type="cylinder" fromto="0 0 0 0 0 0" size="0.05"/>', "objects[0].asset")
