"""Which objects of a scene overlap: objects on the same support and level whose footprints'
bounding boxes intersect by more than a tolerance on both axes.

:func:`overlapping_pairs` finds them with a sweep along one axis per support (sort the boxes by
their lower edge, then each box meets only the boxes whose lower edge comes before its upper
edge; the axis with fewer such candidates is used), in vectorised numpy: a 10,000-object scene
is checked in milliseconds where comparing every pair in Python took minutes.
:func:`overlapping_pairs_naive` is the plain double loop the loader used to run; both give the
same pairs, in the same order.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LEVEL_TOL", "footprint_boxes", "overlapping_pairs", "overlapping_pairs_naive"]

LEVEL_TOL = 0.05
"""Two objects on the same support are on the same level when their bases are less than this
far apart in height (metres); objects on different levels (shelves of one piece) never overlap."""

_CHUNK = 1 << 21  # candidate pairs tested at once (bounds the memory of one step)


def footprint_boxes(objects) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corners of every object's footprint bounding box (``footprint()``).

    Shape:
        N objects -> (N, 2), (N, 2) float64.
    """
    if not objects:
        return np.zeros((0, 2)), np.zeros((0, 2))
    boxes = [o.footprint() for o in objects]
    return np.array([b[0] for b in boxes], np.float64), np.array([b[1] for b in boxes], np.float64)


def _same_level_and_overlap(objects, i: int, j: int, lo, hi, overlap_tol: float) -> bool:
    a, b = objects[i], objects[j]
    same_level = a.support == b.support and abs(a.position[2] - b.position[2]) < LEVEL_TOL
    return bool(same_level and np.all(np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j]) > overlap_tol))


def overlapping_pairs_naive(objects, overlap_tol: float = 0.002) -> list[tuple[int, int]]:
    """Every overlapping pair ``(i, j)``, ``i < j``, in order, by comparing every pair (O(N^2);
    the reference :func:`overlapping_pairs` is tested against)."""
    lo, hi = footprint_boxes(objects)
    return [(i, j) for i in range(len(objects)) for j in range(i + 1, len(objects))
            if _same_level_and_overlap(objects, i, j, lo, hi, overlap_tol)]


def _sweep_candidates(lo_k: np.ndarray, hi_k: np.ndarray, overlap_tol: float):
    """Sort order along one axis and, per sorted box, the end of its candidate window."""
    order = np.argsort(lo_k, kind="stable")
    s_lo, s_hi = lo_k[order], hi_k[order]
    # Overlap on this axis needs min(hi) - max(lo) > tol >= 0, hence lo_q < hi_p (exactly, in
    # floating point) for the later box q: the window is a superset; the exact test follows.
    bound = s_hi if overlap_tol >= 0 else s_hi - 2 * overlap_tol + 1e-9
    end = np.searchsorted(s_lo, bound, side="right")
    counts = np.maximum(end - np.arange(1, len(order) + 1), 0)
    return order, counts


def _group_pairs(idx: np.ndarray, lo, hi, z, overlap_tol: float) -> list[np.ndarray]:
    """Overlapping pairs among the objects ``idx`` (all on one support), as (M, 2) arrays."""
    sweeps = [_sweep_candidates(lo[idx, k], hi[idx, k], overlap_tol) for k in (0, 1)]
    order, counts = min(sweeps, key=lambda s: int(s[1].sum()))
    found = []
    csum = np.cumsum(counts)
    start = 0
    while start < len(order):
        base = csum[start - 1] if start else 0
        stop = max(int(np.searchsorted(csum, base + _CHUNK, side="right")), start + 1)
        c = counts[start:stop]
        total = int(c.sum())
        if total:
            p = np.repeat(np.arange(start, stop), c)
            first = np.repeat(np.cumsum(c) - c, c)
            q = p + 1 + (np.arange(total) - first)
            a, b = idx[order[p]], idx[order[q]]
            ok = np.abs(z[a] - z[b]) < LEVEL_TOL
            ok &= np.all(np.minimum(hi[a], hi[b]) - np.maximum(lo[a], lo[b]) > overlap_tol, axis=1)
            if ok.any():
                found.append(np.stack([np.minimum(a[ok], b[ok]), np.maximum(a[ok], b[ok])], axis=1))
        start = stop
    return found


def overlapping_pairs(objects, overlap_tol: float = 0.002) -> list[tuple[int, int]]:
    """Every overlapping pair ``(i, j)``, ``i < j``, sorted: the objects have the same
    ``support`` (None counts as one support), bases less than :data:`LEVEL_TOL` apart in height,
    and footprint boxes that intersect by more than ``overlap_tol`` on both axes.

    Shape:
        N objects -> a list of M index pairs.
    """
    n = len(objects)
    if n < 2:
        return []
    lo, hi = footprint_boxes(objects)
    z = np.array([o.position[2] for o in objects], np.float64)
    groups: dict = {}
    for i, o in enumerate(objects):
        groups.setdefault(o.support, []).append(i)
    found = []
    for members in groups.values():
        if len(members) > 1:
            found.extend(_group_pairs(np.asarray(members, np.intp), lo, hi, z, overlap_tol))
    if not found:
        return []
    pairs = np.concatenate(found)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return [(int(a), int(b)) for a, b in pairs]
