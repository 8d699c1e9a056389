"""Camera conventions: intrinsics, back-projection, normals, pose checks (the simulator
converters are tested in tests/sim_envs/test_camera_converters.py)."""

import numpy as np
import pytest

from conceptfusion.cameras import (
    backproject,
    check_pose,
    intrinsics_from_fovy,
    normal_map,
    project_points,
)
from conceptfusion.errors import PoseError


def test_intrinsics_from_fovy():
    K = intrinsics_from_fovy(90.0, 640, 480)
    # fy = 0.5 * 480 / tan(45 deg) = 240
    assert K[1, 1] == pytest.approx(240.0) and K[0, 0] == pytest.approx(240.0)
    assert K[0, 2] == 319.5 and K[1, 2] == 239.5


def test_backproject_and_project_round_trip():
    K = intrinsics_from_fovy(90.0, 5, 3)  # f = 1.5, c = (2, 1)
    depth = np.full((3, 5), 2.0, np.float32)
    v = backproject(depth, K)
    # pixel (u=4, v=2): x = (4 - 2) / 1.5 * 2 = 2.6667, y = (2 - 1) / 1.5 * 2 = 1.3333
    assert v[2, 4] == pytest.approx([8 / 3, 4 / 3, 2.0])
    uv, z = project_points(v.reshape(-1, 3), K)
    assert uv[-1] == pytest.approx([4.0, 2.0]) and z[-1] == 2.0
    depth[0, 0] = np.nan
    depth[0, 1] = -1
    assert np.isnan(backproject(depth, K)[0, :2]).all()


def test_normals_of_a_tilted_plane_face_the_camera():
    K = intrinsics_from_fovy(60.0, 32, 24)
    u, v = np.meshgrid(np.arange(32), np.arange(24))
    # plane z = 2 + 0.5 x in the camera frame: depth solves z = 2 + 0.5 * (u - cx) / fx * z
    x_over_z = (u - K[0, 2]) / K[0, 0]
    depth = (2.0 / (1 - 0.5 * x_over_z)).astype(np.float32)
    n = normal_map(backproject(depth, K))
    expect = np.array([0.5, 0.0, -1.0]) / np.sqrt(1.25)
    assert np.allclose(n[5, 5], expect, atol=1e-4)
    assert np.isnan(n[0]).all() and np.isnan(n[:, -1]).all()


def test_pose_checks():
    assert np.array_equal(check_pose(np.eye(4)), np.eye(4))
    bad = np.eye(4)
    bad[0, 0] = -1.0  # mirror
    with pytest.raises(PoseError, match="det"):
        check_pose(bad)
    with pytest.raises(PoseError, match="finite"):
        check_pose(np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match=r"expected shape \(4, 4\)"):
        check_pose(np.eye(3))
