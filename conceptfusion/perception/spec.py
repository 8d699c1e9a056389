"""Which perception a map is built with, by name: :class:`PerceptionSpec` and the encoder names.

A spec's string form is exactly the encoder spec the harness stores in its records
(``"embedded"``, ``"oracle"``, ``"oracle-open"``, ``"hf:openai/clip-vit-base-patch32"``);
:meth:`PerceptionSpec.parse` checks the names and loads nothing.
:func:`~conceptfusion.perception.featurizer.make_featurizer` turns a spec into a featurizer.
"""

from __future__ import annotations

from dataclasses import dataclass

from conceptfusion.errors import UnknownNameError
from conceptfusion.names import unknown_name_error
from conceptfusion.perception.features import check_mode
from conceptfusion.perception.masks.registry import PROPOSERS, rgbd_config
from conceptfusion.perception.registry import DEFAULT_ENCODER, ENCODERS

__all__ = ["ORACLE", "ORACLE_OPEN", "ORACLE_ENCODERS", "SEARCH_PROPOSER", "PerceptionSpec", "encoder_name", "is_oracle",
           "perception_names"]

ORACLE = "oracle"
"""The encoder name of privileged oracle perception (not an encoder of the registry)."""

ORACLE_OPEN = "oracle-open"
"""The encoder name of privileged oracle perception with ground-truth grounding of descriptions
(:class:`~conceptfusion.perception.oracle_featurizers.GroundedOracleFeaturizer`; not an encoder
of the registry)."""

ORACLE_ENCODERS: frozenset[str] = frozenset({ORACLE, ORACLE_OPEN})
"""The privileged oracle encoder names: ground-truth features with no image tower."""

SEARCH_PROPOSER = "rgbd:fixed_size_pixels=19200"
"""The object-search agents' mask proposals: the RGB-D proposer with the region sizes it uses on
a 160x120 frame held in pixels (``fixed_size_pixels``), so the search's 320x240 frames segment
objects down to 19 pixels on their own instead of 77 (identical to ``"rgbd"`` at 160x120)."""


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


def encoder_name(encoder: str) -> str:
    """The name an encoder spec starts with: the text before ``:``, stripped, lower case
    (``"oracle-open:min_pixels=20"`` -> ``"oracle-open"``, ``"hf:openai/clip-vit-base-patch32"`` -> ``"hf"``)."""
    return str(encoder).strip().partition(":")[0].strip().lower()


def is_oracle(encoder: "str | PerceptionSpec") -> bool:
    """Whether an encoder spec names an oracle (privileged ground truth), with or without its
    argument (``"oracle-open:min_pixels=20"``); False for any other string."""
    return encoder_name(encoder.encoder if isinstance(encoder, PerceptionSpec) else encoder) in ORACLE_ENCODERS
