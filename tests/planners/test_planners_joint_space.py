"""Joint-space planning for a planar 2-link arm around a circular obstacle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planners.errors import UnknownPlannerError
from planners.joint_space import plan_joint_path

LINK = (1.0, 1.0)
OBSTACLE_C = np.array([1.2, 1.2])
OBSTACLE_R = 0.3
LOWER = np.array([-math.pi, -math.pi])
UPPER = np.array([math.pi, math.pi])


def arm_points(q: np.ndarray, samples: int = 25) -> np.ndarray:
    """Points along both links of the planar arm (base at the origin).

    Shape: q (2,) -> (2 * samples, 2).
    """
    elbow = LINK[0] * np.array([math.cos(q[0]), math.sin(q[0])])
    tip = elbow + LINK[1] * np.array([math.cos(q[0] + q[1]), math.sin(q[0] + q[1])])
    t = np.linspace(0.0, 1.0, samples)[:, None]
    return np.vstack([t * elbow, elbow + t * (tip - elbow)])


def collision_free(q: np.ndarray) -> bool:
    return bool(np.min(np.linalg.norm(arm_points(q) - OBSTACLE_C, axis=1)) > OBSTACLE_R)


def _dense(path: np.ndarray, step: float = 0.005) -> np.ndarray:
    out = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        out.extend(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.array(out)


START = np.array([0.0, 0.0])  # arm along +x
GOAL = np.array([math.pi / 2, 0.0])  # arm along +y


def test_straight_joint_motion_hits_the_obstacle():
    # Sanity check of the scene: at q = (pi/4, 0) the arm runs along y = x through the obstacle.
    assert not collision_free(np.array([math.pi / 4, 0.0]))
    assert collision_free(START) and collision_free(GOAL)


def test_arm_path_avoids_obstacle():
    res = plan_joint_path(START, GOAL, LOWER, UPPER, collision_free, time_limit=2.0, seed=0, resolution=0.01)
    assert res.status == "solved", res.reason
    assert res.path.shape[1] == 2 and len(res.path) >= 3
    np.testing.assert_allclose(res.path[0], START)
    np.testing.assert_allclose(res.path[-1], GOAL)
    dense = _dense(res.path)
    assert all(collision_free(q) for q in dense)
    assert np.all(dense >= LOWER) and np.all(dense <= UPPER)


def test_joint_plan_is_deterministic_for_a_seed():
    a = plan_joint_path(START, GOAL, LOWER, UPPER, collision_free, seed=5)
    b = plan_joint_path(START, GOAL, LOWER, UPPER, collision_free, seed=5)
    assert a.solved and b.solved
    np.testing.assert_array_equal(a.path, b.path)


def test_start_and_goal_in_collision():
    inside = np.array([math.pi / 4, 0.0])
    res = plan_joint_path(inside, GOAL, LOWER, UPPER, collision_free)
    assert res.status == "start_in_collision" and res.path.shape == (0, 2)
    res = plan_joint_path(START, inside, LOWER, UPPER, collision_free)
    assert res.status == "goal_in_collision" and "goal" in res.reason


def test_impossible_goal_times_out():
    # A wall of invalid configurations at q0 = 0.8 splits the space (no wrap-around in R^2).
    res = plan_joint_path(START, GOAL, LOWER, UPPER, lambda q: abs(q[0] - 0.8) > 0.05, time_limit=0.05)
    assert res.status == "timeout" and res.planner == "rrtconnect"


def test_joint_input_validation():
    with pytest.raises(ValueError, match="outside"):
        plan_joint_path(np.array([4.0, 0.0]), GOAL, LOWER, UPPER, collision_free)
    with pytest.raises(ValueError, match="lower < upper"):
        plan_joint_path(START, GOAL, UPPER, LOWER, collision_free)
    with pytest.raises(ValueError, match=r"expected shape \(2,\)"):
        plan_joint_path(START, np.zeros(3), LOWER, UPPER, collision_free)
    with pytest.raises(TypeError, match="callable"):
        plan_joint_path(START, GOAL, LOWER, UPPER, None)
    with pytest.raises(UnknownPlannerError, match="did you mean"):
        plan_joint_path(START, GOAL, LOWER, UPPER, collision_free, planner="rrtconnct")


def test_errors_in_the_validity_callable_propagate():
    calls = []

    def flaky(q):
        calls.append(1)
        if len(calls) > 2:  # start and goal pass, the planner's first sample fails
            raise ZeroDivisionError("bad collision model")
        return True

    with pytest.raises(ZeroDivisionError, match="bad collision model"):
        plan_joint_path(START, GOAL, LOWER, UPPER, flaky)
