"""Success of a tabletop rearrangement: a pure function of the start and current object poses.

Sides of the dividing line are as seen by a viewer facing ``VIEW_DIR`` (the direction the
environment's fixed camera faces, +y): the right-hand direction of a viewer facing ``f`` is
``(f_y, -f_x)``, so for the shipped scenes (line along y through x = 0) "right" is x > 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim_envs.scenes.format import Scene

__all__ = ["VIEW_DIR", "SIDE_MARGIN", "object_centres", "DISTRACTOR_TOLERANCE", "RearrangeResult", "line_normal", "signed_line_distance", "evaluate"]

VIEW_DIR = (0.0, 1.0)
"""Horizontal direction the viewer faces when saying left and right."""
SIDE_MARGIN = 0.02
"""A target's centre must lie at least this far (m) past the line on its side."""
DISTRACTOR_TOLERANCE = 0.05
"""Every non-target object's centre must move less than this (m, horizontally)."""


def object_centres(scene: Scene, poses) -> np.ndarray:
    """Centre of every object's box (its base centre raised by half its height along the
    object's own z axis): unlike the base centre, it stays put when a ball rolls.

    Shape:
        poses: (n, 7) xyz + quaternion wxyz. returns: (n, 3).
    """
    p = np.asarray(poses, float).reshape(-1, 7)
    w, x, y, z = (p[:, 3:7] / np.linalg.norm(p[:, 3:7], axis=1, keepdims=True)).T
    up = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    heights = np.array([o.size[2] for o in scene.objects], float)
    return p[:, :3] + up * heights[:, None] / 2


def line_normal(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """A point on the dividing line (2,) and its unit normal (2,) pointing to the right side."""
    if scene.line is None:
        raise ValueError(f"scene {scene.id}: expected a dividing line, got none")
    p0, p1 = np.asarray(scene.line[0], float), np.asarray(scene.line[1], float)
    d = p1 - p0
    if np.linalg.norm(d) < 1e-9:
        raise ValueError(f"scene {scene.id}: the dividing line has zero length")
    d /= np.linalg.norm(d)
    f = np.asarray(VIEW_DIR, float)
    right = np.array([f[1], -f[0]])
    n = np.array([-d[1], d[0]])
    if abs(n @ right) < 1e-6:
        raise ValueError(f"scene {scene.id}: the line runs across the view direction, so it has no left or right side")
    return p0, (n if n @ right > 0 else -n)


def signed_line_distance(scene: Scene, points_xy) -> np.ndarray:
    """Signed distance (m) of points from the line, positive on the right side.

    Shape:
        points_xy: (n, 2). returns: (n,).
    """
    p0, n = line_normal(scene)
    return (np.asarray(points_xy, float).reshape(-1, 2) - p0) @ n


@dataclass(frozen=True)
class RearrangeResult:
    """Per-object details of a success judgement.

    Shape:
        ``target_past_line`` (k,) signed distance past the line towards each goal side (m);
        ``displacement`` (n,) horizontal displacement of every object from its start (m).
    """

    success: bool
    targets_done: tuple[bool, ...]
    target_past_line: np.ndarray
    distractors_still: bool
    displacement: np.ndarray
    max_distractor_displacement: float

    def summary(self) -> dict:
        return {
            "success": self.success, "targets_done": list(self.targets_done),
            "target_past_line": self.target_past_line.round(4).tolist(), "distractors_still": self.distractors_still,
            "max_distractor_displacement": round(self.max_distractor_displacement, 4),
        }


def evaluate(
    scene: Scene,
    start_poses,
    poses,
    goals,
    *,
    margin: float = SIDE_MARGIN,
    distractor_tolerance: float = DISTRACTOR_TOLERANCE,
) -> RearrangeResult:
    """Judge success: every goal object's centre (:func:`object_centres`) lies above the table top
    and at least ``margin`` past the line on its side, and every other object's centre moved less
    than ``distractor_tolerance`` horizontally.

    Args:
        goals: sequence of ``(object_id, side)`` pairs or objects with ``object_id`` / ``side``.

    Shape:
        start_poses, poses: (n, 7) (xyz + quaternion wxyz per object, ``scene.objects`` order).
    """
    start = np.asarray(start_poses, float)
    now = np.asarray(poses, float)
    n = len(scene.objects)
    if start.shape != (n, 7) or now.shape != (n, 7):
        raise ValueError(f"poses: expected ({n}, 7) arrays, got {start.shape} and {now.shape}")
    ids = [o.id for o in scene.objects]
    pairs = [(g.object_id, g.side) if hasattr(g, "object_id") else (g[0], g[1]) for g in goals]
    target_idx = []
    for oid, side in pairs:
        if oid not in ids:
            raise ValueError(f"goal object {oid!r}: scene {scene.id} has objects {ids}")
        if side not in ("left", "right"):
            raise ValueError(f"goal side for {oid!r}: expected 'left' or 'right', got {side!r}")
        target_idx.append(ids.index(oid))
    sign = np.array([1.0 if side == "right" else -1.0 for _, side in pairs])
    c_start, c_now = object_centres(scene, start), object_centres(scene, now)
    past = signed_line_distance(scene, c_now[target_idx, :2]) * sign if target_idx else np.zeros(0)
    t = scene.table
    on_table = np.ones(len(target_idx), bool)
    if t is not None and target_idx:
        inside = np.all(np.abs(c_now[target_idx, :2] - np.asarray(t.center[:2])) <= np.asarray(t.size[:2]) / 2, axis=1)
        on_table = inside & (c_now[target_idx, 2] > t.top_z)
    done = tuple(bool(x) for x in (past >= margin) & on_table)
    disp = np.linalg.norm(c_now[:, :2] - c_start[:, :2], axis=1)
    others = np.setdiff1d(np.arange(n), target_idx)
    still = bool(np.all(disp[others] < distractor_tolerance)) if len(others) else True
    max_other = float(disp[others].max()) if len(others) else 0.0
    return RearrangeResult(bool(all(done) and still), done, past, still, disp, max_other)
