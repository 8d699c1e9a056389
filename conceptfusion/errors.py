"""The error hierarchy of the mapping core.

Every error raised for bad input derives from :class:`ConceptFusionError` and from the
built-in class a caller would expect (``ValueError`` or ``TypeError``), so both
``except ConceptFusionError`` and ``except ValueError`` work.
"""

from __future__ import annotations

__all__ = [
    "ConceptFusionError",
    "ShapeError",
    "DtypeError",
    "PoseError",
    "MapFormatError",
    "MapVersionError",
    "MissingDependencyError",
    "CheckpointError",
]


class ConceptFusionError(Exception):
    """Base class of every error this package raises on purpose."""


class ShapeError(ConceptFusionError, ValueError):
    """An array has the wrong number of dimensions or the wrong size."""


class DtypeError(ConceptFusionError, TypeError):
    """An array has an unsupported dtype."""


class PoseError(ConceptFusionError, ValueError):
    """A pose matrix is not a rigid transform (rotation + translation)."""


class MapFormatError(ConceptFusionError, ValueError):
    """A map file is truncated, corrupt, or not a map file at all."""


class MapVersionError(MapFormatError):
    """A map file was written by a newer format version than this code reads."""


class MissingDependencyError(ConceptFusionError, ImportError):
    """An optional dependency is not installed; the message names the extra."""


class CheckpointError(ConceptFusionError, ValueError):
    """A model checkpoint is incomplete, corrupt, or not the kind of model expected."""
