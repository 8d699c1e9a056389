"""Simulator camera converters: OpenGL-style poses and depth buffers, MuJoCo and PyBullet poses."""

import numpy as np
import pytest

from sim_envs.cameras import opengl_depth_to_metric, opengl_to_opencv_pose
from sim_envs.mujoco.camera import mujoco_camera_pose
from sim_envs.pybullet.camera import pybullet_camera_pose


def test_opengl_conversion_is_an_involution_and_flips_axes():
    T = np.eye(4)
    T[:3, 3] = [1, 2, 3]
    cv = opengl_to_opencv_pose(T)
    assert np.allclose(cv[:3, 1], [0, -1, 0]) and np.allclose(cv[:3, 2], [0, 0, -1])
    assert np.allclose(opengl_to_opencv_pose(cv), T)


def test_mujoco_and_pybullet_converters_agree_on_a_look_down_camera():
    # A camera 2 m above the origin looking straight down, image "up" along world +y.
    # OpenGL camera axes in world: x = +x, y (up) = +y, z (backwards) = +z.
    cv = mujoco_camera_pose([0, 0, 2], np.eye(3).ravel())
    assert np.allclose(cv[:3, 2], [0, 0, -1])  # optical axis looks down
    assert np.allclose(cv[:3, 3], [0, 0, 2])
    # PyBullet view matrix = inverse of the OpenGL camera-to-world, column-major
    gl = np.eye(4)
    gl[:3, 3] = [0, 0, 2]
    view = np.linalg.inv(gl).ravel(order="F")
    assert np.allclose(pybullet_camera_pose(view), cv)


def test_opengl_depth_to_metric():
    near, far = 0.1, 10.0
    z = np.array([[0.5, 2.0]])
    d = (far - far * near / z) / (far - near)  # inverse of the formula
    out = opengl_depth_to_metric(d, near, far)
    assert out == pytest.approx(z, rel=1e-5)
    assert np.isinf(opengl_depth_to_metric(np.ones((1, 1)), near, far)[0, 0])
