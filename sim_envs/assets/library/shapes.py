"""The registry of procedural shape variants and the one function that builds a shape.

A variant is a builder plus the ranges of its parameters; integer ranges (both ends ``int``)
draw integers. :func:`build_shape` runs a builder and checks that it made a non-empty mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from conceptfusion.errors import SimError, UnknownKeyError
from conceptfusion.names import unknown_name_error
from sim_envs.assets.library.geometry import Part
from sim_envs.assets.library.shapes_built import BUILT_SHAPES
from sim_envs.assets.library.shapes_round import ROUND_SHAPES

__all__ = ["ShapeVariant", "SHAPES", "build_shape"]


@dataclass(frozen=True)
class ShapeVariant:
    """A procedural shape family."""

    name: str
    """Registry key ("mug_round")."""
    builder: Callable[[Mapping[str, float]], list[Part]]
    """Parameters -> parts (z up, arbitrary units)."""
    params: dict[str, tuple[float, float]]
    """Parameter name -> (low, high); both ``int``: an integer parameter."""


SHAPES: dict[str, ShapeVariant] = {
    name: ShapeVariant(name, fn, dict(ranges)) for name, (fn, ranges) in sorted({**ROUND_SHAPES, **BUILT_SHAPES}.items())
}
"""Every shape variant by name."""


def build_shape(variant: str, params: Mapping[str, float], *, where: str = "shape") -> list[Part]:
    """The parts of ``variant`` with ``params``.

    Raises:
        UnknownKeyError: no such variant (naming the nearest ones).
        SimError: a parameter is missing, or the builder made no triangles (``where`` names
            the instance in the message).
    """
    if variant not in SHAPES:
        raise unknown_name_error("shape variant", variant, SHAPES, listing="", error=UnknownKeyError)
    spec = SHAPES[variant]
    missing = sorted(set(spec.params) - set(params))
    if missing:
        raise SimError(f"{where}: shape variant {variant!r} needs parameters {missing}")
    parts = spec.builder(dict(params))
    if not parts or sum(len(p.mesh.faces) for p in parts) == 0:
        raise SimError(f"{where}: shape variant {variant!r} built an empty mesh")
    for p in parts:
        if not np.all(np.isfinite(p.mesh.vertices)):
            raise SimError(f"{where}: shape variant {variant!r} built non-finite vertices")
    return parts
