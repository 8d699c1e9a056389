"""Pure-pursuit path following for a differential-drive (unicycle) base.

Command convention: ``(linear, angular)`` = forward speed along the robot's heading (m/s) and
yaw rate (rad/s, positive counter-clockwise seen from above, z up). Pose is ``(x, y, yaw)`` in
the world frame, yaw measured from +x towards +y. A holonomic base can use the same output by
sending ``linear * (cos yaw, sin yaw)`` with the yaw rate.

Each step: project the pose on the path (never moving backwards along it, so an L-shaped or
self-approaching path is followed in order), take the point ``lookahead`` metres further along
the path, and steer on the circle through it (curvature ``2 * y_r / d^2`` with ``y_r`` its
lateral offset in the robot frame). When the target is far behind the heading the base turns in
place first; near the goal it slows down; within ``goal_tolerance`` of the last waypoint (and
near the end of the path in arc length) it stops and reports ``done``.

The follower is pure: :func:`pure_pursuit_step` takes a :class:`TrackingState` and returns the
next one with the command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planners._checks import as_float_array, positive_float
from planners.errors import PlannerInputError, PlannerTypeError

__all__ = ["PurePursuitConfig", "TrackingState", "TrackingCommand", "pure_pursuit_step"]


@dataclass(frozen=True)
class PurePursuitConfig:
    """Gains and limits of the pure-pursuit follower."""

    lookahead: float = 0.4
    """Distance along the path from the projected pose to the steering target, metres."""
    max_linear: float = 0.5
    """Forward speed limit, m/s (the base never reverses)."""
    max_angular: float = 1.5
    """Yaw-rate limit, rad/s."""
    goal_tolerance: float = 0.1
    """Distance to the last waypoint at which the base stops and reports done, metres."""
    turn_in_place_angle: float = math.pi / 3
    """Heading error to the target (rad) above which the base turns in place instead of driving."""
    slowdown_distance: float = 0.5
    """Distance to the goal (m) below which the speed ramps down linearly (floor: ``min_linear``)."""
    min_linear: float = 0.05
    """Lowest forward speed while driving, m/s, so the goal is always reached."""

    def __post_init__(self) -> None:
        for name in ("lookahead", "max_linear", "max_angular", "goal_tolerance", "turn_in_place_angle"):
            positive_float(name, getattr(self, name))
        positive_float("slowdown_distance", self.slowdown_distance, allow_zero=True)
        positive_float("min_linear", self.min_linear)
        if self.min_linear > self.max_linear:
            raise PlannerInputError(f"min_linear ({self.min_linear}) exceeds max_linear ({self.max_linear})")
        if self.turn_in_place_angle > math.pi:
            raise PlannerInputError(f"turn_in_place_angle: expected at most pi, got {self.turn_in_place_angle}")


@dataclass(frozen=True)
class TrackingState:
    """Progress along the path, carried from one step to the next (start with ``TrackingState()``)."""

    progress: float = 0.0
    """Arc length (m) of the pose's projection on the path; never decreases."""


@dataclass(frozen=True)
class TrackingCommand:
    """One control step of the follower.

    Shape:
        target_xy: (2,) world x, y of the lookahead point.
    """

    linear: float
    """Forward speed, m/s."""
    angular: float
    """Yaw rate, rad/s (counter-clockwise positive)."""
    done: bool
    """True when the pose is within ``goal_tolerance`` of the last waypoint (command is zero)."""
    target_xy: np.ndarray
    """The lookahead point steered towards."""
    cross_track_error: float
    """Distance from the pose to its projection on the path, metres."""


def _point_at(path: np.ndarray, cum: np.ndarray, s: float) -> np.ndarray:
    """Point at arc length ``s`` (clamped to the path)."""
    if s >= cum[-1]:
        return path[-1].copy()
    i = int(np.searchsorted(cum, s, side="right")) - 1
    i = min(max(i, 0), len(path) - 2)
    seg = cum[i + 1] - cum[i]
    frac = 0.0 if seg <= 0.0 else (s - cum[i]) / seg
    return path[i] + frac * (path[i + 1] - path[i])


def pure_pursuit_step(
    pose_xyyaw,
    path_xy,
    state: TrackingState | None = None,
    config: PurePursuitConfig | None = None,
) -> tuple[TrackingCommand, TrackingState]:
    """One pure-pursuit control step: the command for the current pose, and the next state.

    The projection only searches the path from ``state.progress`` up to ``2 * lookahead + 0.5``
    metres ahead, so the base follows the path in order even where it passes close to itself.

    Shape:
        pose_xyyaw: (3,) world x, y (m) and yaw (rad).
        path_xy: (N, 2) world waypoints, N >= 1, first to last.
    """
    config = PurePursuitConfig() if config is None else config
    state = TrackingState() if state is None else state
    if not isinstance(config, PurePursuitConfig):
        raise PlannerTypeError(f"config: expected a PurePursuitConfig, got {type(config).__name__}")
    if not isinstance(state, TrackingState):
        raise PlannerTypeError(f"state: expected a TrackingState, got {type(state).__name__}")
    pose = as_float_array("pose_xyyaw", pose_xyyaw, (3,))
    path = as_float_array("path_xy", path_xy, (None, 2))
    if len(path) == 0:
        raise PlannerInputError("path_xy: expected at least one waypoint, got none")
    if len(path) == 1:
        path = np.vstack([path, path])
    xy, yaw = pose[:2], float(pose[2])

    seg = np.diff(path, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = float(cum[-1])

    # Project on segments that overlap the search window [progress, progress + window].
    window = 2.0 * config.lookahead + 0.5
    lo_s = min(state.progress, total)
    cand = (cum[1:] >= lo_s) & (cum[:-1] <= lo_s + window)
    idx = np.flatnonzero(cand)
    if len(idx) == 0:
        idx = np.array([len(seg) - 1])
    a, d, length = path[idx], seg[idx], seg_len[idx]
    safe = np.where(length > 0.0, length, 1.0)
    t = np.where(length > 0.0, np.einsum("ij,ij->i", xy - a, d) / safe**2, 0.0)
    # Clamp the projection to the window so that it cannot slip behind the recorded progress.
    s_seg = cum[idx] + np.clip(t, 0.0, 1.0) * length
    s_seg = np.clip(s_seg, lo_s, lo_s + window)
    local_t = np.where(length > 0.0, (s_seg - cum[idx]) / safe, 0.0)
    proj = a + local_t[:, None] * d
    dist = np.linalg.norm(proj - xy, axis=1)
    best = int(np.argmin(dist))
    progress = float(max(s_seg[best], lo_s))
    cross_track = float(dist[best])
    new_state = TrackingState(progress=progress)

    goal = path[-1]
    to_goal = float(np.linalg.norm(goal - xy))
    # The remaining-length test keeps a path that returns near its start from ending at once.
    if to_goal <= config.goal_tolerance and total - progress <= 2.0 * config.goal_tolerance + 1e-9:
        return TrackingCommand(0.0, 0.0, True, goal.copy(), cross_track), TrackingState(progress=total)

    target = _point_at(path, cum, progress + config.lookahead)
    dx, dy = target - xy
    c, s = math.cos(yaw), math.sin(yaw)
    x_r, y_r = c * dx + s * dy, -s * dx + c * dy
    d2 = x_r * x_r + y_r * y_r
    heading_error = math.atan2(y_r, x_r)

    if abs(heading_error) > config.turn_in_place_angle or d2 <= 1e-12:
        angular = math.copysign(config.max_angular, heading_error) if d2 > 1e-12 else 0.0
        return TrackingCommand(0.0, angular, False, target, cross_track), new_state

    curvature = 2.0 * y_r / d2
    linear = config.max_linear
    if config.slowdown_distance > 0.0 and to_goal < config.slowdown_distance:
        linear = max(config.min_linear, config.max_linear * to_goal / config.slowdown_distance)
    angular = linear * curvature
    if abs(angular) > config.max_angular:
        # Keep the curvature, lower the speed.
        linear = config.max_angular / abs(curvature)
        angular = math.copysign(config.max_angular, angular)
    return TrackingCommand(float(linear), float(angular), False, target, cross_track), new_state
