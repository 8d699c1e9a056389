"""Mesh object kinds from pybullet_data: normalised files, and scenes in PyBullet and MuJoCo."""

from __future__ import annotations

import numpy as np
import pytest

from sim_envs import headless  # noqa: F401
from sim_envs.assets.objects import ALL_ASSETS, ASSETS, MESH_ASSETS, get_asset
from sim_envs.assets.meshes import MESH_KINDS, mesh_asset_xml, mesh_name, mesh_texture, normalized_mesh
from sim_envs.scenes.format import Scene, SceneObject, Table

TABLE = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CF_ASSET_CACHE", str(tmp_path_factory.mktemp("assets")))
        yield


def mesh_scene() -> Scene:
    objects = tuple(
        SceneObject(f"obj{i}", kind, MESH_KINDS[kind].category, kind, "red",
                    (-0.45 + 0.15 * (i % 7), -0.15 if i % 2 else 0.15, TABLE.top_z), 0.0, MESH_KINDS[kind].default_size)
        for i, kind in enumerate(MESH_KINDS)
    )
    return Scene("mesh-test", "tabletop", 0, TABLE, objects)


def _read_obj(path):
    v = np.array([[float(x) for x in line.split()[1:4]] for line in path.read_text().splitlines() if line.startswith("v ")])
    vt = [line for line in path.read_text().splitlines() if line.startswith("vt ")]
    return v, len(vt)


@pytest.mark.parametrize("kind", sorted(MESH_KINDS))
def test_normalised_mesh_is_a_unit_box_on_the_floor_with_uvs(kind):
    v, n_uv = _read_obj(normalized_mesh(kind))
    assert np.allclose(v.min(0), [-0.5, -0.5, 0.0], atol=1e-5) and np.allclose(v.max(0), [0.5, 0.5, 1.0], atol=1e-5)
    assert n_uv == len(v)
    tex = mesh_texture(kind)
    assert (tex is None) == (MESH_KINDS[kind].texture is None)
    if tex is not None:
        assert tex.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_assets_stay_procedural_and_mesh_kinds_are_added_beside_them():
    assert set(ASSETS) == {"box", "book", "can", "mug", "bottle", "bowl", "ball"}
    assert set(MESH_ASSETS) == set(MESH_KINDS) and ALL_ASSETS.keys() == ASSETS.keys() | MESH_ASSETS.keys()
    duck = get_asset("duck")
    assert duck.mesh == "duck" and "a rubber duck" in duck.phrases and duck.category == "duck"
    assert 'material="mat_mesh_duck"' in duck.geoms(duck.default_size, "paint_red")
    assert 'material="paint_red"' in get_asset("teddy").geoms((0.1, 0.1, 0.1), "paint_red")
    with pytest.raises(KeyError, match="did you mean"):
        get_asset("duk")


def test_mesh_objects_load_and_render_in_pybullet():
    p = pytest.importorskip("pybullet")
    from sim_envs.pybullet.camera import PyBulletRGBDCamera
    from sim_envs.pybullet.scene import build_pybullet

    client = p.connect(p.DIRECT)
    try:
        sim = build_pybullet(mesh_scene(), client)
        for i, o in enumerate(sim.scene.objects):  # bounding box matches the requested size
            lo, hi = p.getAABB(int(sim.object_body[i]), physicsClientId=client)
            assert np.allclose(np.subtract(hi, lo), o.size, atol=0.045), o.asset  # AABB has a margin
        cam = PyBulletRGBDCamera(client, 200, 150, body_object=sim.body_lut(), renderer="tiny")
        cam.set_pose((0.0, -0.02, 1.4), (0.0, 0.0, 0.4))
        seg = cam.render().segmentation
        assert set(range(len(MESH_KINDS))) <= set(np.unique(seg).tolist())
    finally:
        p.disconnect(physicsClientId=client)


def test_mesh_objects_compile_and_render_in_mujoco():
    mujoco = pytest.importorskip("mujoco")
    from sim_envs.assets.objects import material_xml
    from sim_envs.mujoco.camera import MujocoRGBDCamera

    scene = mesh_scene()
    bodies = "".join(
        f'<body name="{o.id}" pos="{o.position[0]} {o.position[1]} {o.position[2] + 0.001}"><freejoint/>'
        f"{get_asset(o.asset).geoms(o.size, 'paint_red')}</body>"
        for o in scene.objects
    )
    xml = (
        "<mujoco><asset>" + material_xml("paint_red", (0.8, 0.1, 0.1))
        + mesh_asset_xml([(o.asset, o.size) for o in scene.objects])
        + '</asset><worldbody><light pos="0 0 3" dir="0 0 -1"/>'
        + f'<geom type="box" pos="0 0 {TABLE.center[2]}" size="0.6 0.4 0.025"/>{bodies}</worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.nmesh == len(MESH_KINDS)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom_object = np.where(model.geom_bodyid > 0, model.geom_bodyid - 1, -1)
    cam = MujocoRGBDCamera(model, data, 200, 150, geom_object=geom_object)
    try:
        cam.set_pose((0.0, -0.02, 1.4), (0.0, 0.0, 0.4))
        frame = cam.render()
    finally:
        cam.close()
    assert set(range(len(MESH_KINDS))) <= set(np.unique(frame.segmentation).tolist())
    for i, o in enumerate(scene.objects):  # the scaled mesh's world box is the requested size
        g = np.flatnonzero(model.geom_bodyid == i + 1)[0]
        m = model.geom_dataid[g]
        verts = model.mesh_vert[model.mesh_vertadr[m]: model.mesh_vertadr[m] + model.mesh_vertnum[m]]
        world = verts @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        assert np.allclose(np.ptp(world, axis=0), o.size, atol=2e-3), o.asset
        assert world[:, 2].min() == pytest.approx(o.position[2] + 0.001, abs=1e-3)


def test_mesh_asset_xml_declares_each_size_once_and_checks_sizes():
    xml = mesh_asset_xml(["duck", ("duck", MESH_KINDS["duck"].default_size), ("duck", (0.2, 0.1, 0.1))])
    assert xml.count("<mesh ") == 2 and xml.count("<texture ") == 1
    assert mesh_name("duck", (0.2, 0.1, 0.1)) in xml
    with pytest.raises(ValueError, match="positive"):
        mesh_asset_xml([("duck", (0.1, 0.0, 0.1))])
    with pytest.raises(KeyError, match="unknown mesh kind"):
        mesh_asset_xml(["dragon"])
