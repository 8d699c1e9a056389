"""Scenes may use the pybullet_data mesh kinds: they load, build in MuJoCo and segment."""

import dataclasses

import numpy as np
import pytest

from sim_envs.assets.objects import MESH_ASSETS
from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.format import scene_from_json
from sim_envs.scenes.gen_tabletop import generate_tabletop


@pytest.mark.parametrize("kind", ["duck", "soccer_ball", "teddy"])
def test_mesh_object_in_a_mujoco_scene(kind):
    scene = generate_tabletop(1)
    objs = list(scene.objects)
    a = MESH_ASSETS[kind]
    objs[0] = dataclasses.replace(objs[0], asset=kind, name=f"{kind} toy", category=a.category, size=a.default_size)
    scene = scene_from_json(dataclasses.replace(scene, objects=tuple(objs)).to_json())
    sim = build_mujoco(scene)
    cam = MujocoRGBDCamera(sim.model, sim.data, 160, 120, geom_object=sim.geom_object)
    x, y, z = scene.objects[0].position
    cam.set_pose((x, y - 0.45, z + 0.35), (x, y, z + 0.03))
    frame = cam.render()
    cam.close()
    assert (frame.segmentation == 0).sum() > 100  # the mesh object is drawn and labelled
    depth = frame.depth[frame.segmentation == 0]
    assert np.all(np.isfinite(depth)) and np.median(depth) < 0.7


def test_unknown_asset_names_the_known_ones():
    d = generate_tabletop(1).to_json()
    d["objects"][0]["asset"] = "dcuk"
    with pytest.raises(ValueError, match="unknown asset 'dcuk'.*duck"):
        scene_from_json(d)
