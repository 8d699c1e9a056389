"""Pure pursuit on a simulated unicycle, and the blocked-path check that triggers replanning."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planners.occupancy import OccupancyGrid
from planners.replan import check_path_blocked, remaining_path
from planners.tracking import PurePursuitConfig, TrackingState, pure_pursuit_step

L_PATH = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])


def _drive(path, pose, config, dt=0.05, steps=2000):
    """Integrate unicycle kinematics under the follower; return poses, commands, cross-track."""
    state = TrackingState()
    poses, commands = [pose.copy()], []
    for _ in range(steps):
        cmd, state = pure_pursuit_step(pose, path, state, config)
        commands.append(cmd)
        if cmd.done:
            break
        x, y, yaw = pose
        pose = np.array(
            [x + cmd.linear * math.cos(yaw) * dt, y + cmd.linear * math.sin(yaw) * dt, yaw + cmd.angular * dt]
        )
        poses.append(pose.copy())
    return np.array(poses), commands


def _distance_to_path(points, path):
    a, d = path[:-1], np.diff(path, axis=0)
    t = np.clip(np.einsum("nkj,kj->nk", points[:, None, :] - a, d) / np.einsum("kj,kj->k", d, d), 0, 1)
    proj = a + t[..., None] * d
    return np.linalg.norm(points[:, None, :] - proj, axis=2).min(axis=1)


def test_unicycle_follows_l_shaped_path():
    config = PurePursuitConfig(lookahead=0.4, max_linear=0.5, max_angular=1.5, goal_tolerance=0.1)
    poses, commands = _drive(L_PATH, np.array([0.0, 0.0, 0.0]), config)
    assert commands[-1].done
    assert np.linalg.norm(poses[-1, :2] - L_PATH[-1]) <= 0.1 + 0.5 * 0.05  # tolerance + one step
    # Pure pursuit cuts the corner by less than the lookahead.
    assert _distance_to_path(poses[:, :2], L_PATH).max() < 0.4
    # It drove along the first leg before turning: some pose passed x > 2.5 near y = 0.
    assert np.any((poses[:, 0] > 2.5) & (np.abs(poses[:, 1]) < 0.2))
    linear = np.array([c.linear for c in commands])
    angular = np.array([c.angular for c in commands])
    assert linear.min() >= 0.0 and linear.max() <= 0.5 + 1e-12
    assert np.abs(angular).max() <= 1.5 + 1e-12


def test_turns_in_place_when_target_is_behind():
    cmd, _ = pure_pursuit_step([0.0, 0.0, math.pi], L_PATH)
    assert cmd.linear == 0.0 and abs(cmd.angular) == PurePursuitConfig().max_angular
    # Facing -y with the target ahead along +x: a left (counter-clockwise) turn.
    cmd, _ = pure_pursuit_step([0.0, 0.0, -math.pi / 2], L_PATH)
    assert cmd.linear == 0.0 and cmd.angular > 0.0


def test_curvature_golden():
    # Target 0.4 m ahead along a straight path, robot 0.1 m to the right of it, heading +x:
    # the lookahead point is (0.4, 0) from the projection (0, 0) -> in the robot frame
    # (0.4, 0.1); curvature = 2 * 0.1 / (0.16 + 0.01) = 1.17647..., angular = 0.5 * that.
    path = np.array([[0.0, 0.0], [5.0, 0.0]])
    cmd, state = pure_pursuit_step([0.0, -0.1, 0.0], path, config=PurePursuitConfig(slowdown_distance=0.0))
    np.testing.assert_allclose(cmd.target_xy, [0.4, 0.0])
    assert cmd.linear == pytest.approx(0.5)
    assert cmd.angular == pytest.approx(0.5 * 2 * 0.1 / 0.17)
    assert cmd.cross_track_error == pytest.approx(0.1)
    assert state.progress == pytest.approx(0.0)


def test_done_at_goal_and_progress_never_decreases():
    cmd, state = pure_pursuit_step([3.0, 2.95, 1.0], L_PATH, TrackingState(progress=5.5))
    assert cmd.done and cmd.linear == 0.0 and cmd.angular == 0.0
    assert state.progress == pytest.approx(6.0)
    # Standing at the start of a path that ends back near it does not count as done.
    loop = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 0.05]])
    cmd, state = pure_pursuit_step([0.0, 0.0, 0.0], loop)
    assert not cmd.done and cmd.linear > 0.0
    _, later = pure_pursuit_step([0.0, 0.0, 0.0], loop, TrackingState(progress=1.0))
    assert later.progress >= 1.0


def test_tracking_input_validation():
    with pytest.raises(ValueError, match="finite"):
        pure_pursuit_step([0.0, np.nan, 0.0], L_PATH)
    with pytest.raises(ValueError, match="at least one waypoint"):
        pure_pursuit_step([0.0, 0.0, 0.0], np.zeros((0, 2)))
    with pytest.raises(ValueError, match="min_linear"):
        PurePursuitConfig(min_linear=1.0, max_linear=0.5)
    with pytest.raises(TypeError, match="TrackingState"):
        pure_pursuit_step([0.0, 0.0, 0.0], L_PATH, state=0.0)


def _empty_grid():
    return OccupancyGrid(np.array([-1.0, -1.0]), 0.05, np.zeros((100, 100), dtype=bool))


def test_path_blocked_after_obstacle_appears():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    grid = _empty_grid()
    assert not check_path_blocked(grid, path).blocked
    occ = grid.occupied_hw.copy()
    row, col = grid.world_to_cell([2.0, 1.0])
    occ[row - 2 : row + 3, col - 2 : col + 3] = True  # a box on the second leg, around (2.0, 1.0)
    blocked_grid = OccupancyGrid(grid.origin_xy, grid.resolution, occ)
    check = check_path_blocked(blocked_grid, path, position_xy=[0.5, 0.02])
    assert check.blocked and check.segment_index == 1
    assert check.distance_ahead == pytest.approx(1.5)  # from the projection (0.5, 0) to (2, 0)
    assert blocked_grid.is_blocked_xy(check.blocked_xy[None])[0]
    # The box is beyond a 1 m horizon, and already behind a robot that passed it.
    assert not check_path_blocked(blocked_grid, path, position_xy=[0.5, 0.0], horizon=1.0).blocked
    assert not check_path_blocked(blocked_grid, path, position_xy=[2.0, 1.5]).blocked


def test_skip_distance_ignores_robot_cell():
    path = np.array([[0.0, 0.0], [2.0, 0.0]])
    occ = np.zeros((100, 100), dtype=bool)
    grid = _empty_grid()
    row, col = grid.world_to_cell([0.5, 0.0])
    occ[row, col] = True
    g = OccupancyGrid(grid.origin_xy, grid.resolution, occ)
    assert check_path_blocked(g, path, position_xy=[0.5, 0.0]).blocked
    assert not check_path_blocked(g, path, position_xy=[0.5, 0.0], skip_distance=0.1).blocked


def test_remaining_path_golden():
    rest, index = remaining_path(L_PATH, [2.0, 0.3])
    np.testing.assert_allclose(rest, [[2.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    assert index == 0
