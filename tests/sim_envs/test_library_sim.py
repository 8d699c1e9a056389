"""Library instances in scenes: a scene naming "lib:<id>" assets loads, builds and segments in
MuJoCo and in PyBullet; scenes without them build as before; bad names fail naming the field."""

from __future__ import annotations

import numpy as np
import pytest

from sim_envs import headless  # noqa: F401
from sim_envs.assets.library import get_instance, instance_size
from sim_envs.scenes.format import Scene, SceneObject, Table, scene_from_json
from sim_envs.scenes.gen_tabletop import generate_tabletop

TABLE = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))
SAMPLE = ("mug-000", "bowl-001", "wine_glass-001", "apple-002", "toy_car-000", "pb-duck", "can-001", "pb-teddy-1")


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CF_ASSET_CACHE", str(tmp_path_factory.mktemp("assets")))
        yield


def library_scene() -> Scene:
    objects = []
    for k, iid in enumerate(SAMPLE):
        inst = get_instance(iid)
        x, y = -0.42 + 0.28 * (k % 4), -0.15 if k < 4 else 0.15
        objects.append(SceneObject(f"obj{k}", f"{inst.color} {inst.category}", inst.category, inst.asset, inst.color,
                                   (x, y, TABLE.top_z), 0.3 * k, instance_size(iid)))
    scene = Scene("library-test", "tabletop", 0, TABLE, tuple(objects))
    return scene_from_json(scene.to_json(), source="library-test.json")


def test_library_objects_build_and_segment_in_mujoco():
    from sim_envs.mujoco.camera import MujocoRGBDCamera
    from sim_envs.mujoco.scene import build_mujoco

    sim = build_mujoco(library_scene())
    cam = MujocoRGBDCamera(sim.model, sim.data, 200, 150, geom_object=sim.geom_object)
    try:
        cam.set_pose((0.0, -0.75, 1.15), (0.0, 0.0, 0.4))
        frame = cam.render()
    finally:
        cam.close()
    seen = set(np.unique(frame.segmentation).tolist())
    assert set(range(len(SAMPLE))) <= seen
    for i in range(len(SAMPLE)):  # the visual mesh's box is the requested size
        g = np.flatnonzero((sim.geom_object == i) & (sim.model.geom_contype == 0))[0]
        mesh = sim.model.geom_dataid[g]
        v = sim.model.mesh_vert[sim.model.mesh_vertadr[mesh]:sim.model.mesh_vertadr[mesh] + sim.model.mesh_vertnum[mesh]]
        world = sim.data.geom_xpos[g] + v @ sim.data.geom_xmat[g].reshape(3, 3).T
        b = sim.object_body[i]
        local = (world - sim.data.xpos[b]) @ sim.data.xmat[b].reshape(3, 3)  # MuJoCo re-centres meshes; undo it
        assert np.allclose(np.ptp(local, axis=0), sim.scene.objects[i].size, atol=2e-3)
    import mujoco

    for _ in range(200):  # 0.4 s: the objects settle on the table and stay there
        mujoco.mj_step(sim.model, sim.data)
    z = sim.data.xpos[sim.object_body][:, 2]
    assert np.all(np.abs(z - TABLE.top_z) < 0.03)


def test_library_objects_build_and_segment_in_pybullet():
    p = pytest.importorskip("pybullet")
    from sim_envs.pybullet.camera import PyBulletRGBDCamera
    from sim_envs.pybullet.scene import build_pybullet

    client = p.connect(p.DIRECT)
    try:
        sim = build_pybullet(library_scene(), client)
        for i, o in enumerate(sim.scene.objects):
            lo, hi = p.getAABB(int(sim.object_body[i]), physicsClientId=client)
            assert abs((hi[2] - lo[2]) - o.size[2]) < 0.045, o.asset  # AABBs carry a margin
        cam = PyBulletRGBDCamera(client, 200, 150, body_object=sim.body_lut(), renderer="tiny")
        cam.set_pose((0.0, -0.75, 1.15), (0.0, 0.0, 0.4))
        seg = cam.render().segmentation
        assert set(range(len(SAMPLE))) <= set(np.unique(seg).tolist())
        for _ in range(120):
            p.stepSimulation(physicsClientId=client)
        z = np.array([p.getBasePositionAndOrientation(int(b), physicsClientId=client)[0][2] for b in sim.object_body])
        com = TABLE.top_z + 0.4 * np.array([o.size[2] for o in sim.scene.objects])  # PyBullet reports the inertial frame
        assert np.all(np.abs(z - com) < 0.02)  # resting (the teddy leans a little), none falls through
    finally:
        p.disconnect(physicsClientId=client)


def test_scenes_without_library_objects_declare_nothing_of_it():
    from sim_envs.mujoco.scene import build_mjcf

    xml = build_mjcf(generate_tabletop(3))
    assert "lib_" not in xml and "mat_lib" not in xml


def test_a_scene_naming_an_unknown_or_miscoloured_instance_is_refused():
    d = library_scene().to_json()
    d["objects"][1]["asset"] = "lib:bowl-0001"
    with pytest.raises(ValueError, match=r"library-test\.json: objects\[1\]\.asset: unknown library instance 'bowl-0001'; did you mean 'bowl-001'"):
        scene_from_json(d, source="library-test.json")
    d = library_scene().to_json()
    d["objects"][0]["color"] = "purple"
    with pytest.raises(ValueError, match=r"objects\[0\]\.color: library instance 'mug-000' is 'black', got 'purple'"):
        scene_from_json(d, source="library-test.json")
