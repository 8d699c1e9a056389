"""Procedural furniture made of MuJoCo primitives, with the surfaces objects can stand on.

Every kind is a function from a size, a material name and shelf heights to MJCF geoms in the
piece's own frame, plus a function giving its support surfaces in that frame. The frame: origin
at the centre of the footprint on the floor, x across the width, y across the depth with the
back (the side that goes against a wall) towards +y and the front towards -y, z up.

Materials are textured (MuJoCo builtin checker / gradient / flat textures with random marks and
edges), never flat colours: wood, fabric, metal, plaster, and floor finishes (tile, parquet,
carpet).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

__all__ = ["Surface", "FurnitureKind", "FURNITURE", "MATERIALS", "materials_xml", "material_name", "material_look"]


@dataclass(frozen=True)
class Surface:
    """A horizontal rectangle objects can stand on, in the furniture's own frame.

    ``kind``: ``"top"`` (on it), ``"shelf"`` (a shelf level) or ``"inside"`` (the inner floor
    of an open container: what stands there is inside the piece).
    """

    z: float
    lo: tuple[float, float]
    hi: tuple[float, float]
    kind: str = "top"

    def contains(self, xy, tol: float = 0.0) -> bool:
        """Whether local point ``xy`` lies in the rectangle grown by ``tol``."""
        return self.lo[0] - tol <= xy[0] <= self.hi[0] + tol and self.lo[1] - tol <= xy[1] <= self.hi[1] + tol


# name: (builtin, rgb1, rgb2, mark, markrgb, random, texrepeat per metre, specular)
_MATERIAL_SPECS: dict[str, tuple] = {
    "wood": ("checker", (0.60, 0.40, 0.22), (0.55, 0.36, 0.19), "random", (0.40, 0.24, 0.12), 0.15, 4, 0.2),
    "wood_dark": ("checker", (0.36, 0.22, 0.12), (0.32, 0.19, 0.10), "random", (0.22, 0.13, 0.06), 0.15, 4, 0.2),
    "wood_light": ("checker", (0.82, 0.68, 0.48), (0.77, 0.62, 0.42), "random", (0.62, 0.47, 0.30), 0.15, 4, 0.2),
    "wicker": ("checker", (0.78, 0.62, 0.36), (0.55, 0.40, 0.20), "edge", (0.40, 0.28, 0.14), 0.0, 20, 0.1),
    "fabric_grey": ("flat", (0.52, 0.52, 0.55), (0.52, 0.52, 0.55), "random", (0.38, 0.38, 0.42), 0.45, 6, 0.05),
    "fabric_blue": ("flat", (0.22, 0.32, 0.55), (0.22, 0.32, 0.55), "random", (0.14, 0.22, 0.42), 0.45, 6, 0.05),
    "fabric_green": ("flat", (0.30, 0.46, 0.30), (0.30, 0.46, 0.30), "random", (0.20, 0.34, 0.20), 0.45, 6, 0.05),
    "fabric_red": ("flat", (0.60, 0.20, 0.18), (0.60, 0.20, 0.18), "random", (0.45, 0.12, 0.10), 0.45, 6, 0.05),
    "linen": ("flat", (0.90, 0.88, 0.82), (0.90, 0.88, 0.82), "random", (0.78, 0.76, 0.70), 0.35, 6, 0.05),
    "metal": ("gradient", (0.78, 0.79, 0.82), (0.50, 0.51, 0.54), "random", (0.62, 0.63, 0.66), 0.05, 2, 0.8),
    "metal_dark": ("gradient", (0.35, 0.36, 0.38), (0.18, 0.18, 0.20), "random", (0.28, 0.28, 0.30), 0.05, 2, 0.8),
    "plaster_white": ("flat", (0.90, 0.89, 0.86), (0.90, 0.89, 0.86), "random", (0.80, 0.79, 0.76), 0.03, 8, 0.05),
    "plaster_beige": ("flat", (0.86, 0.78, 0.64), (0.86, 0.78, 0.64), "random", (0.76, 0.68, 0.55), 0.03, 8, 0.05),
    "plaster_blue": ("flat", (0.64, 0.74, 0.84), (0.64, 0.74, 0.84), "random", (0.55, 0.65, 0.75), 0.03, 8, 0.05),
    "plaster_green": ("flat", (0.70, 0.80, 0.66), (0.70, 0.80, 0.66), "random", (0.60, 0.70, 0.56), 0.03, 8, 0.05),
    "tile": ("checker", (0.86, 0.86, 0.84), (0.70, 0.72, 0.74), "edge", (0.35, 0.35, 0.35), 0.0, 1.5, 0.3),
    "parquet": ("checker", (0.66, 0.46, 0.26), (0.56, 0.37, 0.20), "edge", (0.30, 0.20, 0.10), 0.0, 3, 0.2),
    "carpet": ("flat", (0.50, 0.42, 0.38), (0.50, 0.42, 0.38), "random", (0.40, 0.32, 0.28), 0.5, 4, 0.0),
    "ground": ("checker", (0.40, 0.45, 0.36), (0.36, 0.41, 0.32), "random", (0.30, 0.35, 0.26), 0.2, 1, 0.0),
}

MATERIALS: tuple[str, ...] = tuple(sorted(_MATERIAL_SPECS))
"""Names of the furniture, wall and floor materials."""


def material_name(name: str) -> str:
    """The MJCF material name of a furniture/wall/floor material (prefixed: no clash with others)."""
    return f"hm_{name}"


def material_look(name: str) -> tuple[str, tuple[float, float, float], tuple[float, float, float]]:
    """``(builtin pattern, rgb1, rgb2)`` of a material of :data:`MATERIALS` (``"checker"``,
    ``"gradient"`` or ``"flat"``), for simulators that draw their own textures."""
    if name not in _MATERIAL_SPECS:
        raise ValueError(f"material: expected one of {list(MATERIALS)}, got {name!r}")
    builtin, rgb1, rgb2 = _MATERIAL_SPECS[name][:3]
    return builtin, rgb1, rgb2


def materials_xml() -> str:
    """``<texture>`` and ``<material>`` elements of every material in :data:`MATERIALS`.

    Textures are 2-D, mapped uniformly in world units (``texuniform``), so a wall shows the
    same pattern scale as a shelf board.
    """
    out = []
    for name in MATERIALS:
        builtin, rgb1, rgb2, mark, markrgb, random, rep, spec = _MATERIAL_SPECS[name]
        f = " ".join
        out.append(
            f'<texture name="htex_{name}" type="2d" builtin="{builtin}" rgb1="{f(f"{c:.3f}" for c in rgb1)}" '
            f'rgb2="{f(f"{c:.3f}" for c in rgb2)}" mark="{mark}" markrgb="{f(f"{c:.3f}" for c in markrgb)}" '
            f'random="{random}" width="64" height="64"/>'
            f'<material name="{material_name(name)}" texture="htex_{name}" texuniform="true" texrepeat="{rep} {rep}" '
            f'specular="{spec}" shininess="{0.5 * spec:.2f}"/>'
        )
    return "".join(out)


def _box(c, half, mat: str) -> str:
    """A box geom from its centre and half sizes."""
    return (
        f'<geom type="box" pos="{c[0]:.4f} {c[1]:.4f} {c[2]:.4f}" '
        f'size="{half[0]:.4f} {half[1]:.4f} {half[2]:.4f}" material="{material_name(mat)}"/>'
    )


def _inset(lo, hi, m: float) -> tuple[tuple[float, float], tuple[float, float]]:
    return (lo[0] + m, lo[1] + m), (hi[0] - m, hi[1] - m)


_M = 0.03  # margin kept free at the edge of every surface


# --- kinds -----------------------------------------------------------------------------------


def _counter(size, mat, shelves):
    w, d, h = size
    return _box((0, 0.03, (h - 0.04) / 2), (w / 2 - 0.01, d / 2 - 0.03, (h - 0.04) / 2), mat) + _box(
        (0, 0, h - 0.02), (w / 2, d / 2, 0.02), "metal"
    )


def _counter_surfaces(size, shelves):
    w, d, h = size
    return [Surface(h, *_inset((-w / 2, -d / 2), (w / 2, d / 2), _M))]


def _table(size, mat, shelves):
    w, d, h = size
    legs = "".join(
        _box((sx * (w / 2 - 0.06), sy * (d / 2 - 0.06), (h - 0.04) / 2), (0.025, 0.025, (h - 0.04) / 2), mat)
        for sx in (-1, 1)
        for sy in (-1, 1)
    )
    return _box((0, 0, h - 0.02), (w / 2, d / 2, 0.02), mat) + legs


def _top_surfaces(size, shelves):
    w, d, h = size
    return [Surface(h, *_inset((-w / 2, -d / 2), (w / 2, d / 2), _M))]


def _desk(size, mat, shelves):
    w, d, h = size
    t = 0.03
    return (
        _box((0, 0, h - t / 2), (w / 2, d / 2, t / 2), mat)
        + _box((-(w / 2 - t / 2), 0, (h - t) / 2), (t / 2, d / 2 - 0.01, (h - t) / 2), mat)
        + _box((w / 2 - t / 2, 0, (h - t) / 2), (t / 2, d / 2 - 0.01, (h - t) / 2), mat)
        + _box((0, d / 2 - 0.03, h * 0.6), (w / 2 - t, 0.01, h * 0.25), mat)
    )


def _shelf_unit(size, mat, shelves, *, panels: bool):
    """Boards at each shelf height and at the top; side and back panels or corner posts."""
    w, d, h = size
    t = 0.02
    parts = [_box((0, 0, z - t / 2), (w / 2 - (t if panels else 0), d / 2 - (0.005 if panels else 0), t / 2), mat) for z in (*shelves, h)]
    if panels:
        parts.append(_box((-(w / 2 - t / 2), 0, h / 2), (t / 2, d / 2, h / 2), mat))
        parts.append(_box((w / 2 - t / 2, 0, h / 2), (t / 2, d / 2, h / 2), mat))
        parts.append(_box((0, d / 2 - 0.005, h / 2), (w / 2 - t, 0.005, h / 2), mat))
    else:
        post = "metal_dark" if mat == "metal" else mat
        parts += [_box((sx * (w / 2 - 0.015), sy * (d / 2 - 0.015), h / 2), (0.015, 0.015, h / 2), post) for sx in (-1, 1) for sy in (-1, 1)]
    return "".join(parts)


def _shelf_surfaces(size, shelves, *, panels: bool, inner_kind: str = "shelf"):
    w, d, h = size
    side = 0.02 if panels else 0.03
    back = 0.01 if panels else 0.03
    lo, hi = (-w / 2 + side + _M, -d / 2 + _M), (w / 2 - side - _M, d / 2 - back - _M)
    return [Surface(float(z), lo, hi, inner_kind) for z in shelves] + [Surface(h, *_inset((-w / 2, -d / 2), (w / 2, d / 2), _M))]


def _cabinet(size, mat, shelves):
    w, d, h = size
    t = 0.02
    plinth = _box((0, 0.01, 0.03), (w / 2 - t, d / 2 - 0.02, 0.03), "wood_dark")
    return _shelf_unit(size, mat, shelves, panels=True) + plinth


def _sofa(size, mat, shelves):
    w, d, h = size
    seat, arm, back = 0.42, 0.18, 0.22
    feet = "".join(_box((sx * (w / 2 - 0.08), sy * (d / 2 - 0.08), 0.04), (0.03, 0.03, 0.04), "wood_dark") for sx in (-1, 1) for sy in (-1, 1))
    return (
        feet
        + _box((0, 0, 0.08 + (seat - 0.08) / 2), (w / 2 - arm, d / 2, (seat - 0.08) / 2), mat)
        + _box((0, d / 2 - back / 2, (h + 0.08) / 2), (w / 2 - arm, back / 2, (h - 0.08) / 2), mat)
        + _box((-(w / 2 - arm / 2), 0, (0.6 + 0.08) / 2), (arm / 2, d / 2, (0.6 - 0.08) / 2), mat)
        + _box((w / 2 - arm / 2, 0, (0.6 + 0.08) / 2), (arm / 2, d / 2, (0.6 - 0.08) / 2), mat)
    )


def _sofa_surfaces(size, shelves):
    w, d, h = size
    return [Surface(0.42, (-w / 2 + 0.18 + _M, -d / 2 + _M), (w / 2 - 0.18 - _M, d / 2 - 0.22 - _M))]


def _bed_top(size) -> float:
    return min(0.55, 0.5 * size[2])


def _bed(size, mat, shelves):
    w, d, h = size
    top = _bed_top(size)
    frame_h = top - 0.2
    return (
        _box((0, 0, frame_h / 2), (w / 2, d / 2, frame_h / 2), "wood")
        + _box((0, -0.02, frame_h + 0.1), (w / 2 - 0.03, d / 2 - 0.05, 0.1), mat)
        + _box((0, d / 2 - 0.03, h / 2), (w / 2, 0.03, h / 2), "wood")
        + _box((0, d / 2 - 0.25, top + 0.05), (w / 2 - 0.15, 0.17, 0.05), "linen")
    )


def _bed_surfaces(size, shelves):
    w, d, h = size
    return [Surface(_bed_top(size), (-w / 2 + 0.03 + _M, -d / 2 + _M), (w / 2 - 0.03 - _M, d / 2 - 0.45))]


def _chair_seat(size) -> float:
    return min(0.46, 0.5 * size[2])


def _chair(size, mat, shelves):
    w, d, h = size
    s = _chair_seat(size)
    legs = "".join(_box((sx * (w / 2 - 0.03), sy * (d / 2 - 0.03), (s - 0.04) / 2), (0.02, 0.02, (s - 0.04) / 2), mat) for sx in (-1, 1) for sy in (-1, 1))
    return legs + _box((0, 0, s - 0.02), (w / 2, d / 2, 0.02), mat) + _box((0, d / 2 - 0.02, (s + h) / 2), (w / 2, 0.02, (h - s) / 2), mat)


def _chair_surfaces(size, shelves):
    w, d, h = size
    return [Surface(_chair_seat(size), (-w / 2 + _M, -d / 2 + _M), (w / 2 - _M, d / 2 - 0.04 - _M))]


def _basket(size, mat, shelves):
    w, d, h = size
    t, f = 0.015, 0.02
    return (
        _box((0, 0, f / 2), (w / 2, d / 2, f / 2), mat)
        + _box((-(w / 2 - t / 2), 0, h / 2), (t / 2, d / 2, h / 2), mat)
        + _box((w / 2 - t / 2, 0, h / 2), (t / 2, d / 2, h / 2), mat)
        + _box((0, -(d / 2 - t / 2), h / 2), (w / 2 - t, t / 2, h / 2), mat)
        + _box((0, d / 2 - t / 2, h / 2), (w / 2 - t, t / 2, h / 2), mat)
    )


def _basket_surfaces(size, shelves):
    w, d, h = size
    return [Surface(0.02, (-w / 2 + 0.015 + 0.01, -d / 2 + 0.015 + 0.01), (w / 2 - 0.015 - 0.01, d / 2 - 0.015 - 0.01), "inside")]


@dataclass(frozen=True)
class FurnitureKind:
    """A procedural furniture kind."""

    category: str
    """What it is ("bookshelf", "sofa", ...)."""
    phrases: tuple[str, ...]
    """Descriptions that hold for every instance."""
    default_size: tuple[float, float, float]
    """Width (x), depth (y), height (z) in metres."""
    default_material: str
    """One of :data:`MATERIALS`."""
    geoms: Callable[[tuple[float, float, float], str, tuple[float, ...]], str]
    """(size, material, shelf heights) -> MJCF geoms in the piece's frame."""
    surfaces: Callable[[tuple[float, float, float], tuple[float, ...]], list[Surface]]
    """(size, shelf heights) -> support surfaces in the piece's frame."""
    shelf_fractions: tuple[float, ...] = ()
    """Default shelf heights as fractions of the height (empty: a kind without shelves)."""
    container: bool = False
    """Objects on its ``"inside"`` surfaces are inside it."""

    def default_shelves(self, height: float) -> tuple[float, ...]:
        """Shelf board heights (metres, tops of the boards) for a piece of this height."""
        return tuple(round(f * height, 3) for f in self.shelf_fractions)


def _panel_unit(size, mat, shelves):
    return _shelf_unit(size, mat, shelves, panels=True)


def _open_unit(size, mat, shelves):
    return _shelf_unit(size, mat, shelves, panels=False)


FURNITURE: dict[str, FurnitureKind] = {
    "counter": FurnitureKind("counter", ("a kitchen counter", "a worktop"), (1.6, 0.6, 0.9), "wood_light", _counter, _counter_surfaces),
    "dining table": FurnitureKind("dining table", ("a table to eat at",), (1.4, 0.85, 0.75), "wood", _table, _top_surfaces),
    "coffee table": FurnitureKind("coffee table", ("a low table", "a table in front of the sofa"), (1.0, 0.55, 0.42), "wood_dark", _table, _top_surfaces),
    "desk": FurnitureKind("desk", ("a desk", "a table to work at"), (1.2, 0.6, 0.75), "wood_light", _desk, _top_surfaces),
    "shelf": FurnitureKind(
        "shelf", ("an open shelf", "a metal rack"), (1.0, 0.4, 1.5), "metal", _open_unit,
        lambda s, sh: _shelf_surfaces(s, sh, panels=False), (0.08, 0.4, 0.72),
    ),
    "bookshelf": FurnitureKind(
        "bookshelf", ("a bookcase", "shelves for books"), (0.9, 0.35, 1.8), "wood", _panel_unit,
        lambda s, sh: _shelf_surfaces(s, sh, panels=True), (0.05, 0.27, 0.48, 0.68, 0.87),
    ),
    "cabinet": FurnitureKind(
        "cabinet", ("an open cabinet", "a cupboard without doors"), (0.8, 0.45, 0.9), "wood_dark", _cabinet,
        lambda s, sh: _shelf_surfaces(s, sh, panels=True, inner_kind="inside"), (0.08, 0.5), container=True,
    ),
    "sofa": FurnitureKind("sofa", ("a couch", "somewhere to sit"), (2.0, 0.85, 0.8), "fabric_grey", _sofa, _sofa_surfaces),
    "bed": FurnitureKind("bed", ("a bed", "somewhere to sleep"), (1.6, 2.0, 1.0), "fabric_blue", _bed, _bed_surfaces),
    "chair": FurnitureKind("chair", ("a chair", "a seat"), (0.45, 0.45, 0.9), "wood", _chair, _chair_surfaces),
    "basket": FurnitureKind("basket", ("a basket", "an open storage box"), (0.45, 0.35, 0.2), "wicker", _basket, _basket_surfaces, container=True),
}
"""Furniture kinds by category name."""
