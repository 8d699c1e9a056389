"""PyBullet scene building and RGB-D + segmentation rendering: depth, poses and labels."""

from __future__ import annotations

import numpy as np
import pytest
from pathlib import Path

from conceptfusion.cameras import backproject, transform_points
from sim_envs.pybullet.camera import PyBulletRGBDCamera, forget_client
from sim_envs.pybullet.scene import build_pybullet
from sim_envs.pybullet.shapes import primitive_shapes, texture_png
from sim_envs.scenes.format import Scene, SceneObject, Table

p = pytest.importorskip("pybullet")

TABLE = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))
KINDS = [("box", (0.10, 0.08, 0.08)), ("book", (0.15, 0.11, 0.035)), ("can", (0.066, 0.066, 0.12)),
         ("mug", (0.09, 0.08, 0.10)), ("bottle", (0.07, 0.07, 0.24)), ("bowl", (0.16, 0.16, 0.06)),
         ("ball", (0.09, 0.09, 0.09))]
XY = [(-0.4, -0.2), (-0.15, -0.2), (0.15, -0.2), (0.4, -0.2), (-0.35, 0.15), (0.0, 0.15), (0.35, 0.15)]


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CF_ASSET_CACHE", str(tmp_path_factory.mktemp("assets")))
        yield


def mixed_scene() -> Scene:
    objects = tuple(
        SceneObject(f"obj{i}", f"green {k}", k, k, "green", (x, y, TABLE.top_z), 0.3 * i, s)
        for i, ((k, s), (x, y)) in enumerate(zip(KINDS, XY))
    )
    return Scene("mixed-test", "tabletop", 0, TABLE, objects, ((0.0, -0.4), (0.0, 0.4)))


@pytest.fixture(scope="module")
def loaded():
    client = p.connect(p.DIRECT)
    sim = build_pybullet(mixed_scene(), client)
    for _ in range(120):
        p.stepSimulation(physicsClientId=client)
    yield sim
    forget_client(client)
    p.disconnect(physicsClientId=client)


def _world_points(frame):
    pts = backproject(frame.depth, frame.K)
    return transform_points(frame.cam_to_world, pts.reshape(-1, 3)).reshape(pts.shape)


@pytest.mark.parametrize("eye", [(0.0, 0.0, 1.6), (0.5, -0.9, 1.1)])
def test_table_top_depth_backprojects_to_table_height(loaded, eye):
    lut = np.full(loaded.table_body + 1, -1, np.int32)
    lut[loaded.table_body] = 0  # label the table's pixels
    cam = PyBulletRGBDCamera(loaded.client, 160, 120, body_object=lut, renderer="tiny")
    cam.set_pose(eye, (0.0, 0.0, 0.4))
    frame = cam.render()
    world = _world_points(frame)
    inside = (np.abs(world[..., 0]) < 0.58) & (np.abs(world[..., 1]) < 0.38)
    table = (frame.segmentation == 0) & inside
    assert table.sum() > 0.1 * table.size  # the table top fills a good part of the view
    err = np.abs(world[table][:, 2] - TABLE.top_z)
    legs = np.any(np.abs(np.abs(world[table][:, :2]) - [0.56, 0.36]) < 0.03, axis=1)  # legs below the edge
    assert err[~legs].max() < 0.01 and np.median(err) < 0.002


def test_tiny_renderer_principal_point_puts_a_rolled_view_on_the_plane(loaded):
    # A rolled, tilted view makes depth vary along both image axes, so both cx and cy matter.
    lut = np.full(loaded.table_body + 1, -1, np.int32)
    lut[loaded.table_body] = 0
    cam = PyBulletRGBDCamera(loaded.client, 96, 64, body_object=lut, renderer="tiny")
    cam._view = p.computeViewMatrix([0.6, -0.8, 1.1], [0.0, 0.0, 0.4], [1.0, 0.3, 1.0])
    frame = cam.render()
    world = _world_points(frame)
    table = (frame.segmentation == 0) & (np.abs(world[..., 0]) < 0.45) & (np.abs(world[..., 1]) < 0.3)
    assert table.sum() > 500
    assert np.abs(world[table][:, 2] - TABLE.top_z).max() < 0.002


def test_frame_shapes_pose_and_far_plane(loaded):
    cam = PyBulletRGBDCamera(loaded.client, 64, 48, fovy_deg=45, renderer="tiny")
    cam.set_pose((0.0, 0.0, 1.5), (0.0, 0.0, 0.0))  # straight down: a valid pose despite up = z
    frame = cam.render(segmentation=False)
    assert frame.rgb.shape == (48, 64, 3) and frame.rgb.dtype == np.uint8
    assert frame.depth.shape == (48, 64) and frame.depth.dtype == np.float32
    assert np.all(frame.segmentation == -1)
    assert np.allclose(frame.cam_to_world[:3, 3], [0.0, 0.0, 1.5])
    assert np.allclose(frame.cam_to_world[:3, 2], [0.0, 0.0, -1.0])  # OpenCV z looks down
    assert frame.K[0, 0] == pytest.approx(0.5 * 48 / np.tan(np.radians(22.5)))
    assert tuple(frame.K[:2, 2]) == (32.0, 23.0)  # the tiny renderer's sample positions
    cam.set_pose((0.0, 0.0, 0.5), (0.0, 0.0, 5.0))  # looking up at the empty sky
    assert np.all(np.isinf(cam.render(segmentation=False).depth))


def test_segmentation_covers_each_object_where_it_is(loaded):
    cam = PyBulletRGBDCamera(loaded.client, 320, 240, body_object=loaded.body_lut(), renderer="tiny")
    cam.set_pose((0.0, -0.05, 1.5), (0.0, 0.0, 0.4))
    frame = cam.render()
    world = _world_points(frame)
    for i, o in enumerate(loaded.scene.objects):
        mask = frame.segmentation == i
        assert mask.sum() > 100, o.id
        centre = np.median(world[mask][:, :2], axis=0)
        assert np.linalg.norm(centre - o.position[:2]) < 0.05, o.id
    assert set(np.unique(frame.segmentation)) == set(range(-1, len(loaded.scene.objects)))


def test_objects_are_textured_not_flat(loaded):
    cam = PyBulletRGBDCamera(loaded.client, 160, 120, body_object=loaded.body_lut(), renderer="tiny")
    cam.set_pose((-0.15, -0.35, 0.7), (-0.15, -0.2, 0.4))
    frame = cam.render()
    book = frame.rgb[frame.segmentation == 1].astype(float)
    assert len(book) > 50
    assert len(np.unique(book.round(), axis=0)) > 5  # shades of the gradient texture


def test_primitive_shapes_match_the_mujoco_geoms():
    mug = primitive_shapes("mug", (0.09, 0.08, 0.10))
    assert [s["shapeType"] for s in mug] == [p.GEOM_CYLINDER, p.GEOM_CAPSULE, p.GEOM_CAPSULE]
    assert mug[0]["radius"] == pytest.approx(0.04) and mug[0]["length"] == pytest.approx(0.10)
    assert len(primitive_shapes("bowl", (0.16, 0.16, 0.06))) == 17
    box = primitive_shapes("box", (0.1, 0.2, 0.3))[0]
    assert np.allclose(box["halfExtents"], [0.05, 0.1, 0.15]) and np.allclose(box["pos"], [0, 0, 0.15])


def test_bad_arguments_are_named(loaded):
    with pytest.raises(ValueError, match="renderer: expected one of"):
        PyBulletRGBDCamera(loaded.client, 32, 32, renderer="vulkan")
    with pytest.raises(ValueError, match="width, height"):
        PyBulletRGBDCamera(loaded.client, 0, 32)
    cam = PyBulletRGBDCamera(loaded.client, 32, 32, renderer="tiny")
    with pytest.raises(RuntimeError, match="set_pose"):
        cam.render()
    with pytest.raises(RuntimeError, match="before building the scene"):
        PyBulletRGBDCamera(loaded.client, 32, 32, renderer="egl")  # bodies exist already
    with pytest.raises(ValueError, match="coincide"):
        cam.set_pose((0, 0, 1), (0, 0, 1))
    with pytest.raises(ValueError, match="pattern"):
        texture_png("x", (1, 0, 0), "stripes")


def test_the_egl_plugin_prints_nothing_on_standard_output(tmp_path):
    """PyBullet's EGL plugin prints its GL vendor on a client's first two images and a farewell
    when the client goes; a run's output must not carry them (checked in a fresh process, at the
    level of file descriptor 1, where the native code writes)."""
    import subprocess
    import sys

    code = (
        "import pybullet as p\n"
        "from sim_envs.pybullet.camera import PyBulletRGBDCamera, disconnect_quietly, load_egl_plugin\n"
        "c = p.connect(p.DIRECT)\n"
        "if not load_egl_plugin(c):\n"
        "    print('NO-EGL')\n"
        "cam = PyBulletRGBDCamera(c, 64, 48, renderer='egl' if load_egl_plugin(c) else 'tiny')\n"
        "cam.set_pose([1.0, 0.0, 1.0], [0.0, 0.0, 0.0])\n"
        "for _ in range(3):\n"
        "    cam.render(segmentation=False)\n"
        "disconnect_quietly(c)\n"
        "print('done')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         cwd=str(Path(__file__).resolve().parents[2]))
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stdout.split()
    if lines == ["NO-EGL", "done"]:
        pytest.skip("PyBullet's EGL plugin does not load here: nothing to silence")
    assert out.stdout == "done\n", out.stdout
