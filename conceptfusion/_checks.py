"""Input validation shared by the public functions of the mapping core."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from conceptfusion.errors import DtypeError, ShapeError

_FLOAT_KINDS = "f"
_NUMBER_KINDS = "fiu"


def as_array(name: str, value, *, shape: Sequence[int | None], kinds: str = _NUMBER_KINDS) -> np.ndarray:
    """Return ``value`` as an ndarray after checking its shape and dtype kind.

    Args:
        name: the argument's name, used in error messages.
        value: the array-like to check.
        shape: expected shape; ``None`` entries accept any size.
        kinds: accepted ``dtype.kind`` letters ("f" float, "i" int, "u" unsigned, "b" bool).
    """
    if not isinstance(value, np.ndarray):
        if isinstance(value, (list, tuple)):
            value = np.asarray(value)
        else:
            raise DtypeError(f"{name}: expected a numpy array, got {type(value).__name__}")
    if value.dtype.kind not in kinds:
        raise DtypeError(f"{name}: expected dtype kind in {sorted(kinds)}, got {value.dtype}")
    dims = ["*" if s is None else str(s) for s in shape]
    expected = "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"
    if value.ndim != len(shape) or any(s is not None and s != v for s, v in zip(shape, value.shape)):
        raise ShapeError(f"{name}: expected shape {expected}, got {tuple(value.shape)}")
    return value


def as_float_array(name: str, value, *, shape: Sequence[int | None]) -> np.ndarray:
    """Like :func:`as_array` but only floating dtypes are accepted."""
    return as_array(name, value, shape=shape, kinds=_FLOAT_KINDS)


def check_finite(name: str, value: np.ndarray) -> None:
    """Raise ``ValueError`` naming ``name`` if ``value`` holds NaN or inf."""
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{name}: expected finite values, found NaN or inf")
