"""The one scan function: render a MuJoCo scene from a list of camera poses.

Everything that renders a sequence of views of a scene goes through :func:`iter_views` (lazy)
or :func:`render_views` (a list): the map suites' scans, the tower's training views and floor
calibration, the tabletop demo, the scene overview picture and the benchmarks. Each call makes
one :class:`~sim_envs.mujoco.camera.MujocoRGBDCamera` for the scene and releases it when the
views are done. The standard trajectories are in :mod:`sim_envs.scenes.trajectories`.
"""

from __future__ import annotations

from typing import Iterable, Iterator

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import MujocoScene
from sim_envs.scenes.trajectories import scan_trajectory

__all__ = ["iter_views", "render_views", "scan_views"]


def iter_views(
    sim: MujocoScene,
    poses: Iterable[tuple],
    width: int,
    height: int,
    *,
    geom_labels: np.ndarray | None = None,
    fovy_deg: float = 60.0,
    segmentation: bool = True,
) -> Iterator[RGBDFrame]:
    """Frames of ``sim`` seen from each ``(eye, target)`` pose, one at a time, in pose order.

    ``poses`` is read lazily: the next pose is taken only when the next frame is asked for, so a
    pose generator may change the scene (lights, say) just before its frame renders.

    Args:
        sim: the built scene (:func:`sim_envs.mujoco.scene.build_mujoco`).
        poses: ``(eye, target)`` pairs, world metres, z up.
        width, height: image size in pixels.
        geom_labels: per geom id, the label its pixels report (-1: none); default
            ``sim.geom_object`` (the index into ``scene.objects``).
        fovy_deg: vertical field of view.
        segmentation: also render the label image (otherwise it is all -1; about twice as fast).

    Shape:
        each frame: ``rgb`` (height, width, 3) uint8, ``depth`` (height, width) float32,
        ``K`` (3, 3), ``cam_to_world`` (4, 4), ``segmentation`` (height, width) int32.
    """
    labels = sim.geom_object if geom_labels is None else geom_labels
    cam = MujocoRGBDCamera(sim.model, sim.data, width, height, fovy_deg=fovy_deg, geom_object=labels)
    try:
        for eye, target in poses:
            cam.set_pose(eye, target)
            yield cam.render(segmentation=segmentation)
    finally:
        cam.close()


def render_views(sim: MujocoScene, poses: Iterable[tuple], width: int, height: int, **options) -> list[RGBDFrame]:
    """All frames of :func:`iter_views` as a list; ``options`` are its keyword arguments
    (``geom_labels``, ``fovy_deg``, ``segmentation``)."""
    return list(iter_views(sim, poses, width, height, **options))


def scan_views(
    sim: MujocoScene, num_frames: int, width: int, height: int, *, geom_labels: np.ndarray | None = None
) -> list[RGBDFrame]:
    """The standard scan of ``sim.scene`` (:func:`~sim_envs.scenes.trajectories.scan_trajectory`:
    an orbit around the table, or a room-by-room sweep), ``num_frames`` frames, 60 degree field
    of view; ``geom_labels`` as in :func:`iter_views`."""
    return render_views(sim, scan_trajectory(sim.scene, num_frames), width, height, geom_labels=geom_labels)
