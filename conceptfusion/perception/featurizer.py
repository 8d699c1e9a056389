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
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Iterable, Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from conceptfusion.errors import UnknownNameError
from conceptfusion.frames import RGBDFrame
from conceptfusion.names import unknown_name_error
from conceptfusion.perception.features import PixelFeatures, check_mode
from conceptfusion.perception.masks.registry import PROPOSERS, make_proposer, rgbd_config
from conceptfusion.perception.oracle import (GROUNDED_ORACLE_DIM, GROUNDED_ORACLE_MIN_SCORE, GroundedOracleFeatures, OracleFeatures,
                                             check_min_pixels, drop_small_segments)
from conceptfusion.perception.oracle_floor import ORACLE_TEXT_ENCODER, load_oracle_floor
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.perception.registry import DEFAULT_ENCODER, ENCODERS, make_encoder, parse_encoder_spec

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

ORACLE = "oracle"
"""The encoder name of privileged oracle perception (not an encoder of the registry)."""

ORACLE_MIN_SCORE = load_oracle_floor()
"""Score floor with oracle features, derived, not tuned: read once, at import, from
:data:`~conceptfusion.perception.oracle_floor.ORACLE_FLOOR_FILE`, which
``python -m tower_training.oracle_floor --write`` writes (the midpoint between the lowest score of
an object's own wordings against its label and the highest score of those wordings against the
other objects' labels, over the floor-calibration scenes). A missing or broken file raises
:class:`~conceptfusion.errors.MissingFileError` / :class:`~conceptfusion.errors.CalibrationFileError`
naming it."""

ORACLE_OPEN = "oracle-open"
"""The encoder name of privileged oracle perception with ground-truth grounding of
descriptions (:class:`GroundedOracleFeaturizer`; not an encoder of the registry)."""

ORACLE_OPEN_MIN_SCORE = GROUNDED_ORACLE_MIN_SCORE
"""Score floor with ``oracle-open`` features, derived from the construction (see
:data:`~conceptfusion.perception.oracle.GROUNDED_ORACLE_MIN_SCORE`), not tuned."""

ORACLE_ENCODERS: frozenset[str] = frozenset({ORACLE, ORACLE_OPEN})
"""The privileged oracle encoder names: ground-truth features with no image tower."""


def perception_names() -> list[str]:
    """Every valid encoder name of a :class:`PerceptionSpec`: the registry's, ``"oracle"`` and
    ``"oracle-open"``."""
    return sorted([*ENCODERS, *ORACLE_ENCODERS])


@dataclass(frozen=True)
class PerceptionSpec:
    """Which perception a map is built with; its string form is the ``encoder`` spec.

    Build one from the command line with :meth:`parse` (names checked, nothing loaded) and turn
    it into a featurizer with :func:`make_featurizer`.
    """

    encoder: str = DEFAULT_ENCODER
    """Encoder registry spec (``"embedded"``, ``"embedded:DIR"``, ``"hf:HUB_ID"``,
    ``"onnx:DIR"``, ``"color"``, ...; see :mod:`conceptfusion.perception.registry`) or
    ``"oracle"`` / ``"oracle-open"`` (privileged ground-truth features). Stored in records as given."""
    proposer: str = "rgbd"
    """Mask proposer registry spec (``"rgbd"``, ``"rgbd:KEY=VALUE,..."``, ``"sam:CKPT"``, ``"gt"``);
    unused by the oracle."""
    mode: str = "full"
    """Pixel-feature variant (:data:`conceptfusion.perception.features.FEATURE_MODES`)."""
    uniqueness: bool = True
    """Use the uniqueness term of eq. 5."""

    def __post_init__(self) -> None:
        if not isinstance(self.encoder, str):
            raise TypeError(f"encoder: expected a spec string such as 'embedded', got {type(self.encoder).__name__}")
        if not isinstance(self.proposer, str):
            raise TypeError(f"proposer: expected a spec string such as 'rgbd', got {type(self.proposer).__name__}")
        check_mode(self.mode)
        if not isinstance(self.uniqueness, bool):
            raise TypeError(f"uniqueness: expected a bool, got {type(self.uniqueness).__name__}")

    def __str__(self) -> str:
        return self.encoder

    @property
    def encoder_name(self) -> str:
        """The encoder's registry name (the spec before ``:``, lower case), or an oracle's name."""
        return encoder_name(self.encoder)

    @property
    def privileged(self) -> bool:
        """True for the oracles (``oracle``, ``oracle-open``, with or without an argument)."""
        return self.encoder_name in ORACLE_ENCODERS

    @property
    def oracle_min_pixels(self) -> int:
        """An oracle's ``min_pixels`` (``"oracle-open:min_pixels=20"``: segments smaller than 20
        pixels of a frame get no feature, as if too small to recognise; 0 without the argument).

        Raises:
            ValueError: not an oracle, or an argument other than ``min_pixels=N`` with N an integer >= 0.
        """
        if not self.privileged:
            raise ValueError(f"oracle_min_pixels: encoder {self.encoder!r} is not an oracle")
        return _oracle_min_pixels(self.encoder)

    @classmethod
    def parse(cls, text: "str | PerceptionSpec", *, proposer: str = "rgbd", mode: str = "full",
              uniqueness: bool = True) -> "PerceptionSpec":
        """The spec of a command-line encoder string (a spec is checked and returned as is);
        checks names only, loads no weights.

        Raises:
            UnknownNameError: unknown encoder or proposer name (naming the nearest valid ones).
            ValueError: an oracle's argument other than ``min_pixels=N`` (``"oracle-open:min_pixels=20"``) or an unknown mode.
            TypeError: ``text`` is not a string.
        """
        if isinstance(text, PerceptionSpec):
            return text.checked()
        if not isinstance(text, str):
            raise TypeError(f"encoder spec: expected a string such as 'embedded' or 'hf:openai/clip-vit-base-patch32', "
                            f"got {type(text).__name__}")
        return cls(encoder=text, proposer=proposer, mode=mode, uniqueness=uniqueness).checked()

    def checked(self) -> "PerceptionSpec":
        """This spec, once its encoder and proposer names are known ones (see :meth:`parse`)."""
        text = self.encoder
        _, sep, _ = text.strip().partition(":")
        if self.encoder_name not in perception_names():
            err = unknown_name_error("encoder", self.encoder_name, perception_names())
            if "/" in text and not sep:
                err = UnknownNameError(f"{err} (a model needs a prefix: hf:{text.strip()} for Hugging Face, "
                                       f"onnx:{text.strip()} for an ONNX folder)")
            raise err
        if self.privileged:
            _oracle_min_pixels(text)  # a ValueError naming the argument
        prop, sep, arg = self.proposer.strip().partition(":")
        prop = prop.lower()
        if prop not in PROPOSERS:
            raise unknown_name_error("mask proposer", prop, sorted(PROPOSERS))
        if prop == "rgbd" and sep:
            rgbd_config(arg)  # a ValueError naming the setting
        return self


def _oracle_min_pixels(encoder: str) -> int:
    """``N`` of an oracle spec ``"NAME:min_pixels=N"``, 0 for a bare ``"NAME"``; a ValueError
    naming the spec for any other argument."""
    _, sep, arg = encoder.strip().partition(":")
    if not sep:
        return 0
    key, eq, value = arg.strip().partition("=")
    if key.strip().lower() != "min_pixels" or not eq or not value.strip().isdigit():
        raise ValueError(f"encoder {encoder_name(encoder)!r}: expected no argument or 'min_pixels=N' (N an integer >= 0), "
                         f"got {encoder!r}")
    return int(value)


@runtime_checkable
class FrameFeaturizer(Protocol):
    """One posed RGB-D frame to pixel-aligned features, and texts to the same space."""

    privileged: bool
    """True when the features read ground truth (the oracle, ground-truth masks); results
    built on them must say so."""
    score_floor: float | None
    """The smallest median cosine score of a region that counts as found for a text query
    (calibrated per encoder; None: no floor).

    A featurizer may also say which names its image side was trained to tell apart
    (``vocabulary``, a tuple of str; see :func:`encoder_vocabulary`); callers read it with
    ``getattr(featurizer, "vocabulary", ())``."""

    @property
    def dim(self) -> int:
        """Feature dimension ``d``."""
        ...

    @property
    def encoder(self):
        """The underlying encoder (``encode_text``; ``encode_image`` too unless text-only),
        for image and click queries against the map."""
        ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Unit embeddings of ``texts`` in the features' space. Shape: (n,) -> (n, d) float32."""
        ...

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Start a new scene; ``label_names`` (segmentation id -> name) is what the oracle
        needs, ``label_phrases`` (segmentation id -> every phrase its object answers to) what
        the ``oracle-open`` needs; the others ignore both."""
        ...

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features of one frame. Shape: frame of (H, W) -> PixelFeatures of (H, W)."""
        ...


FLOOR_SETTINGS = ("tabletop", "household", "search")
"""Where text queries are asked: a tabletop (objects close by; the floor every encoder calibrates
first), a household apartment (objects one to a few metres from a robot base's camera, 160x120
frames) or an apartment as the object-search agents see it (the same views at 320x240 with the
small-object proposals of :data:`SEARCH_PROPOSER`)."""

SEARCH_PROPOSER = "rgbd:fixed_size_pixels=19200"
"""The object-search agents' mask proposals: the RGB-D proposer with the region sizes it uses on
a 160x120 frame held in pixels (``fixed_size_pixels``), so the search's 320x240 frames segment
objects down to 19 pixels on their own instead of 77 (identical to ``"rgbd"`` at 160x120)."""

_FALLBACK = {"search": "household", "household": "tabletop"}


def score_floor_key(setting: str) -> str:
    """Where an encoder's metadata keeps its floor for ``setting``
    (``info["metrics"][score_floor_key(setting)]``): ``score_floor`` for tabletops,
    ``score_floor_<setting>`` for the others."""
    return "score_floor" if setting == "tabletop" else f"score_floor_{setting}"


def _score_floor(encoder, setting: str = "tabletop") -> float | None:
    """The calibrated floor an encoder ships for ``setting``: ``info["metrics"]["score_floor"]``
    for tabletops, ``score_floor_household`` for apartments and ``score_floor_search`` for the
    search agents' view of them (:mod:`tower_training.room_floor`); a setting without its own
    floor falls back to household, then tabletop; None without any."""
    metrics = getattr(encoder, "info", {}).get("metrics", {}) if hasattr(encoder, "info") else {}
    while setting != "tabletop":
        if metrics.get(score_floor_key(setting)) is not None:
            return metrics[score_floor_key(setting)]
        setting = _FALLBACK[setting]
    return metrics.get(score_floor_key("tabletop"))


def encoder_vocabulary(encoder) -> tuple[str, ...]:
    """The names an encoder's image side was trained to tell apart, sorted: the train categories
    its metadata records (``info["splits"]["categories"]["train"]``, written by
    :mod:`tower_training.train_v2`); empty when it records none (the v1 tower, CLIP and other
    open encoders, text-only encoders).

    Raises:
        ValueError: the metadata holds a train list that is not a list of non-empty names.
    """
    info = getattr(encoder, "info", None)
    names = (((info or {}).get("splits") or {}).get("categories") or {}).get("train") if isinstance(info, dict) else None
    if names is None:
        return ()
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) and n.strip() for n in names):
        raise ValueError(f"encoder metadata: splits.categories.train: expected a list of non-empty names, got {names!r:.200}")
    return tuple(sorted(set(names)))


def score_floor_for(featurizer, setting: str = "tabletop") -> float | None:
    """The text-query floor a featurizer applies in ``setting`` (one of :data:`FLOOR_SETTINGS`):
    its ``score_floors[setting]`` when it keeps floors per setting, else its one ``score_floor``.

    Raises:
        ValueError: an unknown setting.
    """
    if setting not in FLOOR_SETTINGS:
        raise ValueError(f"setting: expected one of {', '.join(FLOOR_SETTINGS)}, got {setting!r}")
    floors = getattr(featurizer, "score_floors", None)
    return floors[setting] if floors else featurizer.score_floor


class _EncoderBacked:
    """What both featurizers share: the feature space is their encoder's (``dim``,
    ``encode_text``), and the encoder answers image and click queries."""

    _encoder = None

    @property
    def dim(self) -> int:
        return int(self._encoder.dim)

    @property
    def encoder(self):
        return self._encoder

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        return self._encoder.encode_text(texts)


class PerceivedFeaturizer(_EncoderBacked):
    """Mask proposals + encoder embeddings mixed by eqs. 3-6 (what a robot can perceive).

    Args:
        encoder: image + text encoder (``encode_image``, ``encode_text``, ``dim``).
        proposer: mask proposer (``propose(rgb, depth, K)``; a privileged one also gets
            ``segmentation_hw``).
        mode: pixel-feature variant (``"full"``, ``"global"``, ``"local"``).
        uniqueness: use eq. 5's uniqueness term.
        score_floor: the text-query floor in every setting; default: the encoder's calibrated
            ones per setting (``score_floors``, see :func:`score_floor_for`; ``score_floor`` is
            the tabletop one), else None.
    """

    def __init__(self, encoder, proposer, *, mode: str = "full", uniqueness: bool = True,
                 score_floor: float | None = ...) -> None:  # type: ignore[assignment]
        if proposer is None:
            raise ValueError("PerceivedFeaturizer: expected a mask proposer (make_proposer('rgbd'); "
                             "or make_featurizer('oracle') for ground-truth features)")
        self._encoder, self.proposer = encoder, proposer
        self.mode, self.uniqueness = check_mode(mode), bool(uniqueness)
        self.score_floors = {k: _score_floor(encoder, k) if score_floor is ... else score_floor for k in FLOOR_SETTINGS}
        self.score_floor = self.score_floors["tabletop"]
        self.privileged = bool(getattr(proposer, "privileged", False))
        self.vocabulary = encoder_vocabulary(encoder)
        """Names the encoder's image side was trained on (:func:`encoder_vocabulary`)."""

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Nothing to forget (the names and phrases are for the oracles only)."""

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Masks from the proposer, then :func:`~conceptfusion.perception.pipeline.frame_features`.

        Shape:
            frame (H, W) -> PixelFeatures (H, W).
        """
        if self.privileged:
            if frame.segmentation is None:
                raise ValueError("PerceivedFeaturizer: the ground-truth proposer needs the frame's segmentation")
            masks = self.proposer.propose(frame.rgb, frame.depth, frame.K, segmentation_hw=frame.segmentation)
        else:
            masks = self.proposer.propose(frame.rgb, frame.depth, frame.K)
        return frame_features(frame.rgb, masks, self._encoder, uniqueness=self.uniqueness, mode=self.mode)


def encoder_name(encoder: str) -> str:
    """The name an encoder spec starts with: the text before ``:``, stripped, lower case
    (``"oracle-open:min_pixels=20"`` -> ``"oracle-open"``, ``"hf:openai/clip-vit-base-patch32"`` -> ``"hf"``)."""
    return str(encoder).strip().partition(":")[0].strip().lower()


def is_oracle(encoder: "str | PerceptionSpec") -> bool:
    """Whether an encoder spec names an oracle (privileged ground truth), with or without its
    argument (``"oracle-open:min_pixels=20"``); False for any other string."""
    return encoder_name(encoder.encoder if isinstance(encoder, PerceptionSpec) else encoder) in ORACLE_ENCODERS


class OracleFeaturizer(_EncoderBacked):
    """Privileged features: each segment labelled with its name's text embedding.

    Args:
        text_encoder: embeds the names and the queries (``encode_text``, ``dim``).
        score_floor: the text-query floor (default :data:`ORACLE_MIN_SCORE`).
        min_pixels: segments smaller than this many pixels of a frame get no feature
            (:func:`~conceptfusion.perception.oracle.drop_small_segments`; 0: every segment).
    """

    privileged = True
    vocabulary: tuple[str, ...] = ()
    """No learned image side: nothing to contrast a name with."""

    def __init__(self, text_encoder, *, score_floor: float | None = ORACLE_MIN_SCORE, min_pixels: int = 0) -> None:
        self._encoder = text_encoder
        self.score_floor = score_floor
        self.min_pixels = check_min_pixels(min_pixels)
        self._features: OracleFeatures | None = None

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Embed the names of the segmentation ids of the new scene (required; ``label_phrases``
        is ignored)."""
        if not label_names:
            raise ValueError("OracleFeaturizer.reset: expected object names by segmentation id (privileged oracle features)")
        self._features = OracleFeatures(self._encoder, dict(label_names))

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features from ``frame.segmentation`` (required).

        Shape:
            frame (H, W) with segmentation (H, W) int -> PixelFeatures (H, W).
        """
        if self._features is None:
            raise RuntimeError("OracleFeaturizer: call reset(label_names) before features()")
        if frame.segmentation is None:
            raise ValueError("OracleFeaturizer.features: expected the frame's segmentation (privileged)")
        return self._features(drop_small_segments(frame.segmentation, self.min_pixels))


class _GroundingEncoder:
    """The text side of a :class:`GroundedOracleFeaturizer` (``encode_text``, ``dim``), for
    code that asks the featurizer's ``encoder``; text only (no ``encode_image``: image
    queries are not supported)."""

    def __init__(self, featurizer: "GroundedOracleFeaturizer") -> None:
        self._featurizer = featurizer

    @property
    def dim(self) -> int:
        return self._featurizer.dim

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        return self._featurizer.encode_text(texts)


class GroundedOracleFeaturizer:
    """Privileged features with ground-truth grounding of descriptions (encoder ``"oracle-open"``).

    Each segment gets an orthogonal code; a text is embedded as the codes of the segments of the
    current scene whose phrase sets contain it (:class:`~conceptfusion.perception.oracle.GroundedOracleFeatures`),
    so text embeddings depend on the scene (:attr:`scene_dependent_text`): a mapper must not
    keep them across :meth:`reset`. Image queries are not supported (the encoder is text only).

    Args:
        dim: feature dimension (segmentation ids must be below ``dim - 1``).
        score_floor: the text-query floor (default :data:`ORACLE_OPEN_MIN_SCORE`, derived from
            the construction).
        min_pixels: segments smaller than this many pixels of a frame get no feature, an oracle
            that recognises perfectly only what a frame shows at least that large
            (``"oracle-open:min_pixels=N"``; 0: every segment, however small).
    """

    privileged = True
    vocabulary: tuple[str, ...] = ()
    """No learned image side: nothing to contrast a name with."""
    scene_dependent_text = True
    """Text embeddings are the current scene's (a mapper clears its text cache on reset)."""

    def __init__(self, *, dim: int = GROUNDED_ORACLE_DIM, score_floor: float | None = ORACLE_OPEN_MIN_SCORE,
                 min_pixels: int = 0) -> None:
        if not isinstance(dim, int) or dim < 2:
            raise ValueError(f"GroundedOracleFeaturizer: dim: expected an int >= 2, got {dim!r}")
        self._dim = dim
        self.score_floor = score_floor
        self.min_pixels = check_min_pixels(min_pixels)
        self._features: GroundedOracleFeatures | None = None
        self._encoder = _GroundingEncoder(self)

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def encoder(self):
        """A text-only encoder (``encode_text``, ``dim``) grounding texts in the current scene."""
        return self._encoder

    def reset(self, label_names: Mapping[int, str] | None = None,
              label_phrases: Mapping[int, Iterable[str]] | None = None) -> None:
        """Ground the new scene: ``label_phrases`` (segmentation id -> every phrase its object
        answers to) is required; ``label_names`` is not used (a name counts only as one of the
        phrases).

        Raises:
            ValueError: no phrases, or a segmentation id >= ``dim - 1``.
        """
        if not label_phrases:
            raise ValueError("GroundedOracleFeaturizer.reset: expected the phrases each object answers to by segmentation id "
                             "(label_phrases; the environment's privileged info['object_phrases']), got none")
        self._features = GroundedOracleFeatures(dict(label_phrases), dim=self._dim)

    def _grounding(self, what: str) -> GroundedOracleFeatures:
        if self._features is None:
            raise RuntimeError(f"GroundedOracleFeaturizer: call reset(label_phrases=...) before {what}")
        return self._features

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Texts grounded in the current scene. Shape: (n,) -> (n, dim) float32 unit rows."""
        return self._grounding("encode_text()").encode_text(texts)

    def features(self, frame: RGBDFrame) -> PixelFeatures:
        """Features from ``frame.segmentation`` (required).

        Shape:
            frame (H, W) with segmentation (H, W) int -> PixelFeatures (H, W).
        """
        grounding = self._grounding("features()")
        if frame.segmentation is None:
            raise ValueError("GroundedOracleFeaturizer.features: expected the frame's segmentation (privileged)")
        return grounding(drop_small_segments(frame.segmentation, self.min_pixels))


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
