"""Input validation shared by the public functions of the planners package."""

from __future__ import annotations

import numbers
from typing import Sequence

import numpy as np

from planners.errors import PlannerInputError, PlannerTypeError


def as_float_array(name: str, value, shape: Sequence[int | None], *, finite: bool = True) -> np.ndarray:
    """Return ``value`` as a float64 array after checking its shape (``None`` = any size).

    Accepts numpy arrays, lists and tuples of real numbers; booleans and strings are refused.
    """
    if isinstance(value, (list, tuple)):
        try:
            value = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise PlannerTypeError(f"{name}: expected numbers, got {value!r}") from exc
    if not isinstance(value, np.ndarray):
        raise PlannerTypeError(f"{name}: expected a numpy array, got {type(value).__name__}")
    if value.dtype.kind not in "fiu":
        raise PlannerTypeError(f"{name}: expected a numeric dtype, got {value.dtype}")
    dims = ["*" if s is None else str(s) for s in shape]
    expected = "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"
    if value.ndim != len(shape) or any(s is not None and s != v for s, v in zip(shape, value.shape)):
        raise PlannerInputError(f"{name}: expected shape {expected}, got {tuple(value.shape)}")
    value = value.astype(np.float64, copy=False)
    if finite and not np.all(np.isfinite(value)):
        raise PlannerInputError(f"{name}: expected finite values, found NaN or inf")
    return value


def as_bool_grid(name: str, value) -> np.ndarray:
    """Return ``value`` as a read-only, C-contiguous 2-D bool array (a copy)."""
    if not isinstance(value, np.ndarray):
        raise PlannerTypeError(f"{name}: expected a numpy array, got {type(value).__name__}")
    if value.dtype != np.bool_:
        raise PlannerTypeError(f"{name}: expected dtype bool, got {value.dtype}")
    if value.ndim != 2 or value.shape[0] < 1 or value.shape[1] < 1:
        raise PlannerInputError(f"{name}: expected a non-empty (H, W) array, got shape {value.shape}")
    out = np.array(value, dtype=np.bool_, order="C", copy=True)
    out.setflags(write=False)
    return out


def positive_float(name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float after checking it is a finite real > 0 (>= 0 if allowed)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise PlannerTypeError(f"{name}: expected a real number, got {type(value).__name__}")
    value = float(value)
    ok = value >= 0.0 if allow_zero else value > 0.0
    if not np.isfinite(value) or not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise PlannerInputError(f"{name}: expected a finite number {bound}, got {value}")
    return value


def check_seed(value) -> int:
    """Return ``value`` as an int after checking it is a non-negative integer."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise PlannerTypeError(f"seed: expected a non-negative int, got {type(value).__name__}")
    if value < 0:
        raise PlannerInputError(f"seed: expected a non-negative int, got {value}")
    return int(value)
