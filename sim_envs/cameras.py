"""Converters from OpenGL-style simulator cameras to the :mod:`conceptfusion` convention.

MuJoCo and PyBullet cameras are OpenGL-style (x right, y up, looking along -z) and write a
standard [0, 1] perspective depth buffer; the mapping core knows only the OpenCV camera frame
(x right, y down, z forward), 4x4 float64 camera-to-world poses and metric depth along the
optical axis. These converters are the simulator edge between the two; the simulator-specific
ones live next to their cameras (:func:`sim_envs.mujoco.camera.mujoco_camera_pose`,
:func:`sim_envs.pybullet.camera.pybullet_camera_pose`).
"""

from __future__ import annotations

import numpy as np

from conceptfusion.cameras import check_pose
from conceptfusion.errors import ShapeError

__all__ = ["GL_TO_CV", "opengl_to_opencv_pose", "opengl_depth_to_metric"]

GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
"""Flips a camera's y and z axes: OpenGL camera frame <-> OpenCV camera frame (its own inverse)."""


def opengl_to_opencv_pose(cam_to_world_gl_44) -> np.ndarray:
    """Convert an OpenGL-style camera-to-world pose (y up, looking along -z) to OpenCV.

    Shape:
        (4, 4) -> (4, 4) float64. Applying it twice gives back the input.
    """
    T = check_pose(cam_to_world_gl_44)
    return T @ GL_TO_CV


def opengl_depth_to_metric(depth_buffer_hw: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metric depth along the optical axis from a standard [0, 1] OpenGL depth buffer.

    ``z = far * near / (far - (far - near) * d)``; buffer value 1 (nothing hit) gives ``inf``.

    Shape:
        (H, W) -> (H, W) float32.
    """
    if not (0 < near < far):
        raise ValueError(f"near, far: expected 0 < near < far, got {near}, {far}")
    d = np.asarray(depth_buffer_hw, dtype=np.float64)
    if d.ndim != 2:
        raise ShapeError(f"depth_buffer_hw: expected shape (*, *), got {tuple(d.shape)}")
    z = far * near / (far - (far - near) * d)
    z[d >= 1.0] = np.inf
    return z.astype(np.float32)
