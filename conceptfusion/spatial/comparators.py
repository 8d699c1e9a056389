"""3D spatial comparators (3DSCs): relations between two map regions.

The paper's eight comparators, each ``relation(region_a, region_b, *, ...)``. The arguments
are the :class:`~conceptfusion.map.regions.Region` s that two queries selected, or ``None`` when a
query found nothing; a ``None`` argument gives a "not found" :class:`SpatialAnswer` that names
the missing object instead of a guess.

Frame: world coordinates in metres with **z up**. Objects are assumed to stand upright, so
"footprint" means the projection on the xy plane and "height" the z extent.

Robust bounds: map regions carry stray points (depth noise, mis-fused features). Every box
below is taken between the ``trim_pct`` and ``100 - trim_pct`` percentiles of the points on
each axis (numpy's ``"lower"`` / ``"higher"`` methods, so the bounds are real point
coordinates); ``trim_pct=0`` gives the plain min / max.

Summary of the geometric definitions (each function's docstring has the details):

=================  ==========================================================================
``howFar``         distance between the region centres (the paper's figure); the closest
                   surface-to-surface distance is reported alongside (:func:`closest_distance`)
``isToTheLeft``    a's centre lies more than ``min_offset`` to the viewer's left of b's centre
``isToTheRight``   the mirror image
``onTopOf``        a's bottom within ``contact_tol`` of b's top, footprints overlapping
``under``          ``onTopOf`` with the arguments swapped (b rests on a)
``isBigger``       a's oriented-box volume exceeds b's by more than ``rel_margin``
``canFitInside``   a's sorted oriented extents + ``clearance`` fit within b's sorted extents
``isContained``    a's box lies inside b's box grown by ``tol`` on every side
=================  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from conceptfusion.spatial.geometry import (
    check_nonneg as _check_nonneg,
    check_trim as _check_trim,
    closest_points_distance,
    footprint_overlap as _overlap_fraction,
    oriented_extents,
    robust_bounds,
)
from conceptfusion.map.regions import Region
from conceptfusion.names import unknown_name_error

__all__ = [
    "SpatialAnswer",
    "Comparator",
    "how_far",
    "closest_distance",
    "is_to_the_left",
    "is_to_the_right",
    "on_top_of",
    "under",
    "is_bigger",
    "can_fit_inside",
    "is_contained",
    "robust_bounds",
    "oriented_extents",
    "COMPARATORS",
    "COMPARATOR_NAMES",
    "get_comparator",
]

_UP_3 = np.array([0.0, 0.0, 1.0])
_EPS = 1e-9  # metres: floating-point slack on every threshold comparison
_DEFAULT_NAMES = ("object1", "object2")


@dataclass(frozen=True)
class SpatialAnswer:
    """The result of one comparator call.

    ``value`` is ``None`` whenever an object was not found or the relation could not be
    decided (the reason says why); it is never a guess.
    """

    relation: str
    """The paper's name of the comparator, e.g. ``"howFar"``."""
    value: float | bool | None
    """Metres for ``howFar``; ``True``/``False`` for the others; ``None`` if undecided."""
    found_a: bool
    """Whether the first object was found in the map."""
    found_b: bool
    """Whether the second object was found in the map."""
    reason: str
    """A short human-readable explanation of the value."""
    details: tuple[tuple[str, float], ...] = ()
    """Named intermediate measurements (metres, cubic metres or fractions)."""

    @property
    def found(self) -> bool:
        """Whether both objects were found."""
        return self.found_a and self.found_b

    def detail(self, key: str) -> float:
        """Return the intermediate measurement ``key`` (``KeyError`` naming the valid keys)."""
        for name, value in self.details:
            if name == key:
                return value
        raise KeyError(f"no detail {key!r}; available: {[n for n, _ in self.details]}")


class Comparator(Protocol):
    """A 3DSC: two regions (or ``None`` when not found) in, one :class:`SpatialAnswer` out."""

    def __call__(self, region_a: Region | None, region_b: Region | None, /, **kwargs) -> SpatialAnswer: ...


def _check_region(name: str, region) -> None:
    if region is None:
        return
    if not isinstance(region, Region):
        raise TypeError(f"{name}: expected a Region or None, got {type(region).__name__}")
    pts = region.points_n3
    if not isinstance(pts, np.ndarray) or pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{name}: expected points_n3 of shape (N, 3), got {getattr(pts, 'shape', None)}")
    if pts.shape[0] == 0:
        raise ValueError(f"{name}: region has no points; pass None for an object that was not found")
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"{name}: points_n3 holds NaN or inf")


def _check_names(names) -> tuple[str, str]:
    if (
        not isinstance(names, (tuple, list))
        or len(names) != 2
        or not all(isinstance(n, str) and n.strip() for n in names)
    ):
        raise TypeError(f"names: expected two non-empty strings, got {names!r}")
    return str(names[0]), str(names[1])


def _missing(relation: str, region_a, region_b, names) -> SpatialAnswer | None:
    """Validate the pair; return a not-found answer if either region is ``None``."""
    _check_region("region_a", region_a)
    _check_region("region_b", region_b)
    name_a, name_b = _check_names(names)
    missing = [n for n, r in ((name_a, region_a), (name_b, region_b)) if r is None]
    if not missing:
        return None
    what = " and ".join(repr(n) for n in missing)
    verb = "were" if len(missing) == 2 else "was"
    return SpatialAnswer(
        relation=relation,
        value=None,
        found_a=region_a is not None,
        found_b=region_b is not None,
        reason=f"{relation}: {what} {verb} not found in the map; no answer",
    )


def _center(region: Region, center: str) -> np.ndarray:
    if center == "centroid":
        return region.centroid
    if center == "median":
        return region.median
    raise ValueError(f"center: expected 'centroid' or 'median', got {center!r}")


def _answer(relation: str, value, reason: str, **details: float) -> SpatialAnswer:
    return SpatialAnswer(
        relation=relation,
        value=value,
        found_a=True,
        found_b=True,
        reason=reason,
        details=tuple((k, float(v)) for k, v in details.items()),
    )


# ---------------------------------------------------------------------------------------------
# Distance
# ---------------------------------------------------------------------------------------------


def how_far(
    region_a: Region | None,
    region_b: Region | None,
    *,
    center: str = "centroid",
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``howFar``: the distance in metres between the two objects' centres.

    Definition: Euclidean distance between the region centres (``center="centroid"``, the
    mean point, as in the paper's figure; ``"median"`` is the per-axis median, robust to stray
    points). ``details`` also holds ``"closest"``: the closest surface-to-surface distance,
    the ``trim_pct`` percentile of the point-to-nearest-point distances both ways (0 for
    touching or overlapping objects), and ``"centre"``, equal to ``value``.
    """
    if (miss := _missing("howFar", region_a, region_b, names)) is not None:
        return miss
    trim = _check_trim(trim_pct)
    d = float(np.linalg.norm(_center(region_a, center) - _center(region_b, center)))
    closest = closest_points_distance(region_a.points_n3, region_b.points_n3, trim)
    return _answer(
        "howFar",
        d,
        f"{names[0]!r} and {names[1]!r} are {d:.2f} m apart ({center}s); closest surfaces {closest:.2f} m",
        centre=d,
        closest=closest,
    )


def closest_distance(
    region_a: Region | None,
    region_b: Region | None,
    *,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """The closest surface-to-surface distance in metres (not one of the paper's eight).

    Definition: the ``trim_pct`` percentile (``"lower"`` method) of the distances from every
    point of each region to its nearest point of the other region; ``trim_pct=0`` is the plain
    minimum. Touching or interpenetrating regions give (close to) 0.
    """
    if (miss := _missing("closestDistance", region_a, region_b, names)) is not None:
        return miss
    d = closest_points_distance(region_a.points_n3, region_b.points_n3, _check_trim(trim_pct))
    return _answer("closestDistance", d, f"closest surfaces of {names[0]!r} and {names[1]!r} are {d:.2f} m apart", closest=d)


# ---------------------------------------------------------------------------------------------
# Left / right
# ---------------------------------------------------------------------------------------------


def _lateral(
    relation: str,
    region_a: Region | None,
    region_b: Region | None,
    viewing_direction,
    viewer_position,
    center: str,
    min_offset: float,
    names: tuple[str, str],
    sign: float,
) -> SpatialAnswer:
    """``isToTheLeft`` (``sign`` -1) or ``isToTheRight`` (+1) of a and b, checks included."""
    if (miss := _missing(relation, region_a, region_b, names)) is not None:
        return miss
    min_offset = _check_nonneg("min_offset", min_offset)
    if (viewing_direction is None) == (viewer_position is None):
        raise ValueError(f"{relation}: give exactly one of viewing_direction or viewer_position")
    ca, cb = _center(region_a, center), _center(region_b, center)
    if viewing_direction is not None:
        forward = np.asarray(viewing_direction, dtype=np.float64)
        label = "viewing_direction"
    else:
        origin = np.asarray(viewer_position, dtype=np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ValueError(f"viewer_position: expected 3 finite numbers, got {viewer_position!r}")
        forward = (ca + cb) / 2.0 - origin
        label = None
    if label and (forward.shape != (3,) or not np.all(np.isfinite(forward))):
        raise ValueError(f"viewing_direction: expected 3 finite numbers, got {viewing_direction!r}")
    horizontal = forward - forward @ _UP_3 * _UP_3
    norm = float(np.linalg.norm(horizontal))
    if norm < 1e-9:
        if label:
            raise ValueError(
                "viewing_direction: is vertical (or zero), so left and right are undefined; "
                "give a direction with a horizontal component"
            )
        return _answer(relation, None, "the viewer is directly above or below the objects; left/right undefined")
    right = np.cross(horizontal / norm, _UP_3)
    offset = float((ca - cb) @ right) * sign  # > 0: a is on the asked side of b
    side = "right" if sign > 0 else "left"
    value = offset > min_offset
    if value:
        why = f"{names[0]!r} is {offset:.2f} m to the {side} of {names[1]!r}"
    elif offset > -min_offset:
        why = f"{names[0]!r} is roughly in line with {names[1]!r} ({offset:+.2f} m to the {side})"
    else:
        why = f"{names[0]!r} is {-offset:.2f} m to the other side of {names[1]!r}"
    return _answer(relation, value, why + " as seen by the viewer", offset=offset)


def is_to_the_left(
    region_a: Region | None,
    region_b: Region | None,
    *,
    viewing_direction=None,
    viewer_position=None,
    center: str = "median",
    min_offset: float = 0.02,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``isToTheLeft``: is a to the viewer's left of b?

    Give exactly one of ``viewing_direction`` (world (3,) vector the viewer looks along; for
    an OpenCV camera-to-world pose ``T``, ``T[:3, 2]``) or ``viewer_position`` (world (3,)
    point; the viewer then looks at the midpoint of the two centres, ``T[:3, 3]`` for a pose).
    The direction is projected on the horizontal plane; with z up, the viewer's right is
    ``forward x up`` and left is its opposite.

    Definition: the horizontal offset of a's centre from b's centre along the viewer's left
    axis exceeds ``min_offset`` metres. Centres are per-axis medians by default. ``details``:
    ``"offset"`` (metres, positive towards the left).
    """
    return _lateral("isToTheLeft", region_a, region_b, viewing_direction, viewer_position, center, min_offset, names, -1.0)


def is_to_the_right(
    region_a: Region | None,
    region_b: Region | None,
    *,
    viewing_direction=None,
    viewer_position=None,
    center: str = "median",
    min_offset: float = 0.02,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``isToTheRight``: is a to the viewer's right of b? The mirror of :func:`is_to_the_left`.

    ``details``: ``"offset"`` (metres, positive towards the right).
    """
    return _lateral("isToTheRight", region_a, region_b, viewing_direction, viewer_position, center, min_offset, names, 1.0)


# ---------------------------------------------------------------------------------------------
# Support
# ---------------------------------------------------------------------------------------------


def _support(
    relation: str,
    region_a: Region | None,
    region_b: Region | None,
    names: tuple[str, str],
    contact_tol: float,
    min_overlap: float,
    require_contact: bool,
    trim_pct: float,
    *,
    a_on_top: bool,
) -> SpatialAnswer:
    """Does the top region rest on the bottom one (a on b when ``a_on_top``, else b on a)? Checks included."""
    if (miss := _missing(relation, region_a, region_b, names)) is not None:
        return miss
    trim_pct = _check_trim(trim_pct)
    top, bottom, top_name, bottom_name = (
        (region_a, region_b, names[0], names[1]) if a_on_top else (region_b, region_a, names[1], names[0])
    )
    tol = _check_nonneg("contact_tol", contact_tol)
    frac_min = float(min_overlap)
    if not 0.0 < frac_min <= 1.0:
        raise ValueError(f"min_overlap: expected a fraction in (0, 1], got {min_overlap!r}")
    lo_t, hi_t = robust_bounds(top.points_n3, trim_pct)
    lo_b, hi_b = robust_bounds(bottom.points_n3, trim_pct)
    gap = float(lo_t[2] - hi_b[2])  # > 0: the top object floats above the bottom one
    overlap = _overlap_fraction(lo_t, hi_t, lo_b, hi_b)
    contact = abs(gap) <= tol + _EPS
    above = gap >= -tol - _EPS
    vertical_ok = contact if require_contact else above
    value = vertical_ok and overlap >= frac_min
    if value:
        why = f"{top_name!r} rests on {bottom_name!r} (gap {gap:+.3f} m, footprint overlap {overlap:.0%})"
    elif not vertical_ok and gap > 0:
        why = f"{top_name!r} floats {gap:.3f} m above the top of {bottom_name!r} (no contact)"
    elif not vertical_ok:
        why = f"the bottom of {top_name!r} is {-gap:.3f} m below the top of {bottom_name!r}"
    else:
        why = f"the footprints of {top_name!r} and {bottom_name!r} overlap only {overlap:.0%}"
    return _answer(relation, value, why, gap=gap, overlap=overlap)


def on_top_of(
    region_a: Region | None,
    region_b: Region | None,
    *,
    contact_tol: float = 0.03,
    min_overlap: float = 0.3,
    require_contact: bool = True,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``onTopOf``: does a rest on b?

    Definition (support), on the robust boxes of both regions:

    * vertical contact: ``|bottom(a) - top(b)| <= contact_tol`` metres (with
      ``require_contact=False``: only ``bottom(a) >= top(b) - contact_tol``, i.e. anywhere
      above);
    * horizontal overlap: the intersection of the two xy footprints covers at least
      ``min_overlap`` of the smaller footprint.

    ``details``: ``"gap"`` = bottom(a) - top(b) in metres, ``"overlap"`` the fraction.
    """
    return _support("onTopOf", region_a, region_b, names, contact_tol, min_overlap, bool(require_contact), trim_pct,
                    a_on_top=True)


def under(
    region_a: Region | None,
    region_b: Region | None,
    *,
    contact_tol: float = 0.03,
    min_overlap: float = 0.3,
    require_contact: bool = True,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``under``: is a underneath b, i.e. does b rest on a?

    Exactly :func:`on_top_of` with the roles swapped: ``under(a, b) == onTopOf(b, a)``.
    ``details``: ``"gap"`` = bottom(b) - top(a), ``"overlap"``.
    """
    return _support("under", region_a, region_b, names, contact_tol, min_overlap, bool(require_contact), trim_pct,
                    a_on_top=False)


# ---------------------------------------------------------------------------------------------
# Size
# ---------------------------------------------------------------------------------------------


def is_bigger(
    region_a: Region | None,
    region_b: Region | None,
    *,
    measure: str = "volume",
    rel_margin: float = 0.05,
    min_thickness: float = 0.01,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``isBigger``: is a bigger than b?

    Definition: sizes come from :func:`oriented_extents` (yaw-aligned robust box), each extent
    floored at ``min_thickness`` so that flat objects seen as one surface keep a volume.
    ``measure="volume"`` compares the box volumes, ``"max_extent"`` the longest sides. a is
    bigger when ``size(a) > size(b) * (1 + rel_margin)``; sizes within the margin are "about
    the same" and give ``False`` both ways. ``details``: ``"size_a"``, ``"size_b"`` (cubic
    metres or metres).
    """
    if (miss := _missing("isBigger", region_a, region_b, names)) is not None:
        return miss
    margin = _check_nonneg("rel_margin", rel_margin)
    floor = _check_nonneg("min_thickness", min_thickness)
    trim = _check_trim(trim_pct)
    ext_a = np.maximum(oriented_extents(region_a.points_n3, trim), floor)
    ext_b = np.maximum(oriented_extents(region_b.points_n3, trim), floor)
    if measure == "volume":
        size_a, size_b, unit = float(np.prod(ext_a)), float(np.prod(ext_b)), "m^3"
    elif measure == "max_extent":
        size_a, size_b, unit = float(ext_a.max()), float(ext_b.max()), "m"
    else:
        raise ValueError(f"measure: expected 'volume' or 'max_extent', got {measure!r}")
    value = size_a > size_b * (1.0 + margin)
    if value:
        why = f"{names[0]!r} ({size_a:.4g} {unit}) is bigger than {names[1]!r} ({size_b:.4g} {unit})"
    elif size_b > size_a * (1.0 + margin):
        why = f"{names[0]!r} ({size_a:.4g} {unit}) is smaller than {names[1]!r} ({size_b:.4g} {unit})"
    else:
        why = f"{names[0]!r} and {names[1]!r} are about the same size ({size_a:.4g} vs {size_b:.4g} {unit})"
    return _answer("isBigger", value, why, size_a=size_a, size_b=size_b)


def can_fit_inside(
    region_a: Region | None,
    region_b: Region | None,
    *,
    clearance: float = 0.01,
    allow_rotation: bool = True,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``canFitInside``: could a be placed inside b?

    Definition: b's outer box stands in for its inner cavity (walls are thin; ``clearance``
    absorbs them). With ``allow_rotation=True`` both :func:`oriented_extents` are sorted
    largest first and a fits when every sorted extent of a plus ``clearance`` is at most the
    matching extent of b; sorting allows any 90-degree reorientation, including laying a
    tall object on its side. With ``allow_rotation=False`` the world-axis robust extents are
    compared axis by axis. ``details``: ``"margin"``, the tightest extent difference
    (b - a - clearance; negative when it does not fit).
    """
    if (miss := _missing("canFitInside", region_a, region_b, names)) is not None:
        return miss
    gap = _check_nonneg("clearance", clearance)
    trim = _check_trim(trim_pct)
    if allow_rotation:
        ext_a = np.sort(oriented_extents(region_a.points_n3, trim))[::-1]
        ext_b = np.sort(oriented_extents(region_b.points_n3, trim))[::-1]
    else:
        lo_a, hi_a = robust_bounds(region_a.points_n3, trim)
        lo_b, hi_b = robust_bounds(region_b.points_n3, trim)
        ext_a, ext_b = hi_a - lo_a, hi_b - lo_b
    margin = float(np.min(ext_b - ext_a - gap))
    value = margin >= -_EPS
    dims_a = " x ".join(f"{e:.2f}" for e in ext_a)
    dims_b = " x ".join(f"{e:.2f}" for e in ext_b)
    verb = "fits" if value else "does not fit"
    why = f"{names[0]!r} ({dims_a} m) {verb} inside {names[1]!r} ({dims_b} m) with {gap:.3f} m clearance"
    return _answer("canFitInside", value, why, margin=margin)


def is_contained(
    region_a: Region | None,
    region_b: Region | None,
    *,
    tol: float = 0.02,
    open_top: bool = False,
    trim_pct: float = 1.0,
    names: tuple[str, str] = _DEFAULT_NAMES,
) -> SpatialAnswer:
    """``isContained``: is a inside b?

    Definition: a's robust axis-aligned box lies within b's robust box grown by ``tol``
    metres on every side. ``open_top=True`` drops the upper z bound (bread sticking out of a
    bowl). ``details``: ``"protrusion"``, how far a sticks out of b's box at worst (metres,
    <= 0 when inside), and ``"inside_fraction"``, the share of a's points inside b's grown box.
    """
    if (miss := _missing("isContained", region_a, region_b, names)) is not None:
        return miss
    t = _check_nonneg("tol", tol)
    trim = _check_trim(trim_pct)
    lo_a, hi_a = robust_bounds(region_a.points_n3, trim)
    lo_b, hi_b = robust_bounds(region_b.points_n3, trim)
    out = np.concatenate([lo_b - lo_a, hi_a - hi_b])  # > 0: a sticks out on that side
    if open_top:
        out = np.delete(out, 5)
        hi_b = hi_b.copy()
        hi_b[2] = np.inf
    protrusion = float(out.max())
    pts = region_a.points_n3
    inside = np.all((pts >= lo_b - t - _EPS) & (pts <= hi_b + t + _EPS), axis=1)
    value = protrusion <= t + _EPS
    if value:
        why = f"{names[0]!r} lies inside the box of {names[1]!r} (tolerance {t:.3f} m)"
    else:
        why = f"{names[0]!r} sticks out of {names[1]!r} by {protrusion:.3f} m"
    return _answer("isContained", value, why, protrusion=protrusion, inside_fraction=float(inside.mean()))


# ---------------------------------------------------------------------------------------------
# Lookup table
# ---------------------------------------------------------------------------------------------

COMPARATORS: dict[str, Comparator] = {
    "howFar": how_far,
    "isToTheRight": is_to_the_right,
    "isToTheLeft": is_to_the_left,
    "isContained": is_contained,
    "onTopOf": on_top_of,
    "under": under,
    "isBigger": is_bigger,
    "canFitInside": can_fit_inside,
}
"""The paper's eight comparator names, in the order of its prompt, to their functions."""

COMPARATOR_NAMES: tuple[str, ...] = tuple(COMPARATORS)
"""The eight names, in the paper's order."""

_BY_LOWER = {name.lower(): name for name in COMPARATORS}


def get_comparator(name: str) -> Comparator:
    """Return the comparator called ``name`` (a paper name; case-insensitive).

    Raises ``ValueError`` naming the nearest valid names for an unknown name.
    """
    if not isinstance(name, str):
        raise TypeError(f"name: expected a str, got {type(name).__name__}")
    canonical = _BY_LOWER.get(name.strip().lower())
    if canonical is not None:
        return COMPARATORS[canonical]
    raise unknown_name_error("spatial comparator", name, COMPARATORS, cutoff=0.5, key=lambda n: n.strip().lower(),
                             listing=f"valid: {', '.join(COMPARATOR_NAMES)}")
