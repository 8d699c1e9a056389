"""Push geometry for the tabletop task: "push the goldfish to the right of the yellow line".

Everything lives in the horizontal table plane (world frame, z up); z components of directions
are ignored and heights are carried through unchanged.

Side convention: ``"left"`` / ``"right"`` are as seen by a viewer facing the horizontal
direction ``view_dir`` (typically the camera's forward axis projected on the table). The
viewer's right-hand direction is ``(f_y, -f_x)`` for a facing direction ``f = (f_x, f_y)``
(facing +x, right is -y). "Right of the line" is the half-plane of the table on that side of
the dividing line. A line that runs left-right in front of the viewer (parallel to the right
direction) has no left or right side: that is a :class:`DegenerateGeometryError`.

The push runs perpendicular to the line, towards the requested side: the pusher starts at an
approach point behind the object, touches its back, and pushes until the object's centre lies
``margin`` past the line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from planners._checks import as_float_array, positive_float
from planners.errors import DegenerateGeometryError, PlannerInputError

__all__ = ["PushPlan", "plan_push", "side_normal"]

Side = Literal["left", "right"]

_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class PushPlan:
    """A straight push of an object across a dividing line.

    Shape:
        push_direction: (3,) unit vector, z = 0, perpendicular to the line, towards the side.
        pre_push_xyz, contact_xyz, push_end_xyz, object_goal_xyz: (3,) world points at the
        object's height.
    """

    push_direction: np.ndarray
    """Unit push direction in the table plane."""
    signed_distance: float
    """Object centre's distance past the line along ``push_direction`` now (negative: wrong side)."""
    push_distance: float
    """How far the object centre must travel: ``max(0, margin - signed_distance)``."""
    already_on_side: bool
    """True when the centre is already at least ``margin`` past the line (nothing to push)."""
    pre_push_xyz: np.ndarray
    """Approach point: ``back_offset + approach_clearance`` behind the centre."""
    contact_xyz: np.ndarray
    """Where the pusher meets the object's back: ``back_offset`` behind the centre."""
    push_end_xyz: np.ndarray
    """Where the pusher stops: the contact point moved by ``push_distance``."""
    object_goal_xyz: np.ndarray
    """Where the object centre ends up: the centre moved by ``push_distance``."""


def side_normal(line_dir, view_dir, side: Side) -> np.ndarray:
    """Unit normal of the line in the table plane pointing into the requested side.

    Shape:
        line_dir, view_dir: (2,) or (3,) (z ignored). returns: (2,).
    """
    if side not in ("left", "right"):
        raise PlannerInputError(f"side: expected 'left' or 'right', got {side!r}")
    d = _horizontal("line_dir", line_dir)
    f = _horizontal("view_dir", view_dir)
    d_norm, f_norm = np.linalg.norm(d), np.linalg.norm(f)
    if d_norm < _EPS:
        raise DegenerateGeometryError(
            f"line_dir: the dividing line has no horizontal direction (got {np.asarray(line_dir).tolist()})"
        )
    if f_norm < _EPS:
        raise DegenerateGeometryError(
            f"view_dir: the viewer has no horizontal facing direction (got {np.asarray(view_dir).tolist()})"
        )
    d, f = d / d_norm, f / f_norm
    right = np.array([f[1], -f[0]])
    normal = np.array([-d[1], d[0]])
    alignment = float(normal @ right)
    if abs(alignment) < 1e-6:
        raise DegenerateGeometryError(
            "the dividing line runs left-right across the viewer's view, so it has no left or right side"
        )
    if alignment < 0.0:
        normal = -normal
    return normal if side == "right" else -normal


def plan_push(
    object_xyz,
    line_point,
    line_dir,
    side: Side,
    *,
    view_dir,
    radius: float | None = None,
    footprint_xy=None,
    margin: float = 0.05,
    approach_clearance: float = 0.05,
) -> PushPlan:
    """Plan a straight push that puts the object's centre ``margin`` past the line on ``side``.

    The object's extent behind its centre along the push direction (``back_offset``) comes from
    exactly one of ``radius`` (round footprint) or ``footprint_xy`` (its floor-plane points: the
    largest distance of a point behind the centre, at least 0).

    Shape:
        object_xyz: (3,) the object's centre (e.g. the median of its points), world frame.
        line_point: (2,) or (3,) a point on the dividing line. line_dir: (2,) or (3,).
        view_dir: (2,) or (3,) the horizontal direction the viewer faces.
        footprint_xy: (M, 2) world x, y of the object's points, M >= 1.
    """
    centre = as_float_array("object_xyz", object_xyz, (3,))
    point = _horizontal("line_point", line_point)
    margin = positive_float("margin", margin, allow_zero=True)
    approach_clearance = positive_float("approach_clearance", approach_clearance, allow_zero=True)
    normal = side_normal(line_dir, view_dir, side)
    if (radius is None) == (footprint_xy is None):
        raise PlannerInputError("give exactly one of radius and footprint_xy")
    if radius is not None:
        back_offset = positive_float("radius", radius, allow_zero=True)
    else:
        pts = as_float_array("footprint_xy", footprint_xy, (None, 2))
        if len(pts) == 0:
            raise PlannerInputError("footprint_xy: expected at least one point, got none")
        back_offset = max(0.0, float(np.max(-(pts - centre[:2]) @ normal)))

    signed = float((centre[:2] - point) @ normal)
    push_distance = max(0.0, margin - signed)
    direction = np.array([normal[0], normal[1], 0.0])
    contact = centre - back_offset * direction
    return PushPlan(
        push_direction=direction,
        signed_distance=signed,
        push_distance=push_distance,
        already_on_side=signed >= margin,
        pre_push_xyz=contact - approach_clearance * direction,
        contact_xyz=contact,
        push_end_xyz=contact + push_distance * direction,
        object_goal_xyz=centre + push_distance * direction,
    )


def _horizontal(name: str, value) -> np.ndarray:
    """The x, y part of a (2,) or (3,) vector, checked finite."""
    arr = np.asarray(value) if isinstance(value, (list, tuple)) else value
    if isinstance(arr, np.ndarray) and arr.ndim == 1 and arr.shape[0] == 3:
        return as_float_array(name, arr, (3,))[:2].copy()
    return as_float_array(name, arr, (2,)).copy()
