"""Colours and materials of library instances.

Colours are named RGB triples; the first ten are the scene generator's ``COLORS`` (same values),
so a red library mug and a red v1 mug look alike. Materials say how a surface is patterned (the
procedural texture of :mod:`~sim_envs.assets.library.textures`) and how shiny it renders.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim_envs.assets.objects import COLORS

__all__ = ["PALETTE", "Material", "MATERIALS"]

PALETTE: dict[str, tuple[float, float, float]] = {
    **COLORS,
    "grey": (0.50, 0.50, 0.52),
    "silver": (0.75, 0.76, 0.78),
    "gold": (0.83, 0.66, 0.22),
    "beige": (0.86, 0.78, 0.62),
    "cream": (0.95, 0.92, 0.80),
    "tan": (0.72, 0.55, 0.36),
    "navy": (0.10, 0.14, 0.40),
    "teal": (0.10, 0.52, 0.52),
    "light blue": (0.55, 0.74, 0.92),
    "dark green": (0.08, 0.32, 0.14),
    "maroon": (0.45, 0.08, 0.12),
    "clear": (0.82, 0.88, 0.90),
}
"""Colour names of library instances -> RGB in [0, 1]."""


@dataclass(frozen=True)
class Material:
    """How a material looks."""

    pattern: str
    """Texture pattern: "grain", "brushed", "glaze", "flat", "weave", "fibre", "streak",
    "speckle", "mottle" or "soft"."""
    specular: float
    """Specular intensity in MuJoCo (0..1)."""
    shininess: float
    """Shininess in MuJoCo (0..1)."""
    contrast: float
    """How strongly the pattern varies around the colour (0: flat)."""


MATERIALS: dict[str, Material] = {
    "wood": Material("grain", 0.15, 0.2, 0.2),
    "metal": Material("brushed", 0.8, 0.7, 0.25),
    "ceramic": Material("glaze", 0.5, 0.6, 0.12),
    "plastic": Material("flat", 0.3, 0.4, 0.08),
    "fabric": Material("weave", 0.02, 0.05, 0.3),
    "paper": Material("fibre", 0.05, 0.1, 0.15),
    "glass": Material("streak", 0.9, 0.9, 0.3),
    "rubber": Material("speckle", 0.1, 0.1, 0.2),
    "organic": Material("mottle", 0.3, 0.3, 0.3),
    "wax": Material("soft", 0.2, 0.3, 0.12),
    "stone": Material("speckle", 0.2, 0.2, 0.4),
}
"""Material names -> look. Glass renders opaque and tinted (see the package docstring)."""
