"""Perception as one object: a posed RGB-D frame in, pixel-aligned concept features out.

A map is built with a :class:`FrameFeaturizer`, never with a mode flag. Three implementations:

* :class:`PerceivedFeaturizer`: class-agnostic mask proposals from the frame (a
  :class:`~conceptfusion.perception.masks.base.MaskProposer`) and crop/frame embeddings from an
  encoder (the embedded tower, real CLIP, ...), mixed by the paper's eqs. 3-6 in one of the
  feature modes of :mod:`conceptfusion.perception.features`. It is privileged only when its
  proposer is (``"gt"``, ground-truth masks).
* :class:`OracleFeaturizer` (**privileged**): each pixel gets the text embedding of its
  ground-truth object's name (:class:`~conceptfusion.perception.oracle.OracleFeatures`); it
  reads ``frame.segmentation`` and needs the names of the segmentation ids at :meth:`reset`.
* :class:`GroundedOracleFeaturizer` (**privileged**, encoder ``"oracle-open"``): ground-truth
  segmentation *and* ground-truth grounding of descriptions
  (:class:`~conceptfusion.perception.oracle.GroundedOracleFeatures`): each segment gets an
  orthogonal code and a description is embedded as the codes of the segments whose phrase sets
  contain it, so synonyms, attributes, functions and parent groups are found exactly when they
  name a segment. It needs each id's phrases at :meth:`reset`; its text embeddings depend on the
  scene (``scene_dependent_text``).

All are built from a :class:`PerceptionSpec` (or its command-line string) by the one factory
:func:`make_featurizer`, which loads each encoder once per process. The spec's string form is
exactly the encoder spec the harness stores in its records (``"embedded"``, ``"oracle"``,
``"oracle-open"``, ``"hf:openai/clip-vit-base-patch32"``).

This module holds the factory and re-exports the parts, which live by job:
:mod:`~conceptfusion.perception.spec` (the spec and the encoder names),
:mod:`~conceptfusion.perception.score_floor` (score floors per encoder and setting),
:mod:`~conceptfusion.perception.featurizer_base` (the protocol),
:mod:`~conceptfusion.perception.perceived` and :mod:`~conceptfusion.perception.oracle_featurizers`
(the featurizers).
"""

from __future__ import annotations

import functools

from conceptfusion.perception.featurizer_base import FrameFeaturizer
from conceptfusion.perception.masks.registry import make_proposer
from conceptfusion.perception.oracle_featurizers import GroundedOracleFeaturizer, OracleFeaturizer
from conceptfusion.perception.oracle_floor import ORACLE_TEXT_ENCODER
from conceptfusion.perception.perceived import PerceivedFeaturizer, encoder_vocabulary
from conceptfusion.perception.registry import DEFAULT_ENCODER, ENCODERS, make_encoder, parse_encoder_spec
from conceptfusion.perception.score_floor import (FLOOR_SETTINGS, ORACLE_MIN_SCORE, ORACLE_OPEN_MIN_SCORE, score_floor_for,
                                                  score_floor_key)
from conceptfusion.perception.spec import (ORACLE, ORACLE_ENCODERS, ORACLE_OPEN, SEARCH_PROPOSER, PerceptionSpec, encoder_name,
                                           is_oracle, perception_names)

__all__ = [
    "ORACLE",
    "ORACLE_MIN_SCORE",
    "ORACLE_OPEN",
    "ORACLE_OPEN_MIN_SCORE",
    "ORACLE_ENCODERS",
    "is_oracle",
    "encoder_name",
    "PerceptionSpec",
    "FrameFeaturizer",
    "PerceivedFeaturizer",
    "OracleFeaturizer",
    "GroundedOracleFeaturizer",
    "make_featurizer",
    "load_encoder",
    "perception_names",
    "FLOOR_SETTINGS",
    "score_floor_for",
    "score_floor_key",
    "SEARCH_PROPOSER",
    "encoder_vocabulary",
]


def load_encoder(spec: str):
    """The encoder of a registry spec, loaded once per process (so map suites load it once); a
    name registered anew (``register_encoder(..., replace=True)``) loads its new encoder.

    Raises what :func:`~conceptfusion.perception.registry.make_encoder` raises (nothing is cached then).
    """
    name, _ = parse_encoder_spec(spec)
    return _load_encoder(spec, ENCODERS[name])


@functools.lru_cache(maxsize=4)
def _load_encoder(spec: str, factory) -> object:
    """:func:`make_encoder` cached by spec and the factory registered for it."""
    return make_encoder(spec)


def make_featurizer(spec: "PerceptionSpec | str" = DEFAULT_ENCODER) -> FrameFeaturizer:
    """The featurizer a spec names; its encoder is loaded once per process (:func:`load_encoder`).

    Raises:
        UnknownNameError: unknown encoder or proposer name (naming the nearest valid ones).
        FileNotFoundError, CheckpointError, MissingDependencyError: from loading the encoder.
    """
    spec = PerceptionSpec.parse(spec)
    if spec.encoder_name == ORACLE:
        return OracleFeaturizer(load_encoder(ORACLE_TEXT_ENCODER), min_pixels=spec.oracle_min_pixels)
    if spec.encoder_name == ORACLE_OPEN:
        return GroundedOracleFeaturizer(min_pixels=spec.oracle_min_pixels)
    return PerceivedFeaturizer(load_encoder(spec.encoder), make_proposer(spec.proposer),
                               mode=spec.mode, uniqueness=spec.uniqueness)
