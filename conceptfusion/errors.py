"""The project's one error hierarchy.

Every error raised on purpose, in the mapping core and in the simulator, agent, planner and
harness packages, derives from :class:`ConceptFusionError` and from the built-in class a
caller would expect (``ValueError``, ``TypeError``, ``ImportError``), so both
``except ConceptFusionError`` and ``except ValueError`` work. Packages above the core add their
own subclasses (``sim_envs``: :class:`SimError`; ``agents``: :class:`AgentError`; ``planners``:
:class:`PlannerError`; the harness: :class:`HarnessError`), all defined here so there is one
place to look.
"""

from __future__ import annotations

__all__ = [
    "ConceptFusionError",
    "ShapeError",
    "DtypeError",
    "PoseError",
    "MapFormatError",
    "MapVersionError",
    "FrameFolderError",
    "MissingFileError",
    "MissingDependencyError",
    "CheckpointError",
    "EncoderOutputError",
    "CalibrationFileError",
    "UnknownNameError",
    "UnknownKeyError",
    "SimError",
    "SceneFormatError",
    "AgentError",
    "PlannerError",
    "HarnessError",
    "ReplayFormatError",
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


class FrameFolderError(ConceptFusionError, ValueError):
    """A folder of a user's RGB-D frames (:mod:`conceptfusion.frame_folders`) that cannot be
    mapped: an unknown layout, a frame file without depth, sizes that differ, a pose that is not
    rigid or finite, intrinsics that do not fit the image; the message names the file."""


class MissingFileError(ConceptFusionError, FileNotFoundError):
    """An input file (scene, episode set, map, results) or run folder does not exist; the
    message names the path. Also a ``FileNotFoundError``, as callers have always caught."""


class MissingDependencyError(ConceptFusionError, ImportError):
    """An optional dependency is not installed; the message names the extra."""


class CheckpointError(ConceptFusionError, ValueError):
    """A model checkpoint is incomplete, corrupt, or not the kind of model expected."""


class EncoderOutputError(ConceptFusionError, ValueError):
    """A registered encoder answered with the wrong shape, a NaN or inf, or rows that are not unit
    vectors (:mod:`conceptfusion.perception.checked`); the message names the encoder, the method,
    what was expected and what arrived."""


class CalibrationFileError(ConceptFusionError, ValueError):
    """A calibration data file shipped with the package (such as the oracle's score floor) is
    not valid JSON, of another format or version, or has missing or invalid fields."""


class UnknownNameError(ConceptFusionError, ValueError):
    """A name looked up in a table of named things (agents, encoders, suites, assets) is not
    there; the message names the nearest valid ones (:func:`conceptfusion.names.lookup`)."""


class UnknownKeyError(UnknownNameError, KeyError):
    """An :class:`UnknownNameError` that is also a ``KeyError``, for lookups whose callers have
    always caught ``KeyError`` (assets, mesh kinds). Its text is the message, unquoted."""

    __str__ = Exception.__str__


class SimError(ConceptFusionError, ValueError):
    """Bad input to a simulated scene, episode or environment (:mod:`sim_envs`)."""


class SimTypeError(SimError, TypeError):
    """A :class:`SimError` for a value of the wrong type (a list where a dict is expected, a
    float where an int is); also a ``TypeError``."""


class EnvStateError(SimError, RuntimeError):
    """An environment called in the wrong state: ``step()`` before the first successful
    ``reset()``, after the episode ended (a step returned ``terminated`` or ``truncated``;
    the Gymnasium convention: reset first) or after ``close()``; also a ``RuntimeError``."""


class SceneFormatError(SimError):
    """A scene file is malformed: the message names the file and the field (``objects[2].yaw``)."""


class AgentError(ConceptFusionError, ValueError):
    """Bad input to an agent or the agent registry (:mod:`agents`)."""


class PlannerError(ConceptFusionError, ValueError):
    """Bad input to a planner, or a planning failure raised as an error (:mod:`planners`)."""


class HarnessError(ConceptFusionError, ValueError):
    """Bad settings or files of an evaluation run (:mod:`harness`)."""


class ReplayFormatError(HarnessError):
    """An episode recording (:mod:`harness.replay`) that cannot be read: truncated, corrupt,
    another format or a newer version."""
