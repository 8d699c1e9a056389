"""The concept mapper as agents use it.

The mapper itself is mapping, not agent business: :class:`~conceptfusion.mapper.ConceptMapper`,
:class:`~conceptfusion.mapper.MapperConfig` and
:func:`~conceptfusion.mapper.frame_from_observation` live in :mod:`conceptfusion.mapper` (built by
:func:`conceptfusion.make_mapper`) and are re-exported here for the agents' imports. What is
agents' business stays: :func:`privileged_labels`, the ground-truth labels a privileged mapper
reads from an environment's ``info``.
"""

from __future__ import annotations

from typing import Mapping

from conceptfusion.mapper import ConceptMapper, MapperConfig, frame_from_observation

__all__ = ["ConceptMapper", "MapperConfig", "frame_from_observation", "privileged_labels"]


def privileged_labels(mapper: ConceptMapper, info: Mapping | None) -> dict:
    """The keyword arguments of :meth:`ConceptMapper.reset` from an environment's ``info``:
    ``object_names`` and ``object_phrases`` by segmentation id (object index) when the mapper is
    privileged and ``info`` has them; empty otherwise (no ground truth is read then).

    Shape:
        ``info["object_names"]`` (n,) str, ``info["object_phrases"]`` (n,) lists of str ->
        ``{"object_names": {i: name}, "object_phrases": {i: phrases}}`` (either may be missing).
    """
    if not mapper.privileged or not info:
        return {}
    out = {}
    if "object_names" in info:
        out["object_names"] = dict(enumerate(info["object_names"]))
    if "object_phrases" in info:
        out["object_phrases"] = dict(enumerate(info["object_phrases"]))
    return out
