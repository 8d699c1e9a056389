"""Mask proposers by name: :data:`PROPOSERS` and :func:`make_proposer`.

Proposers, by registry name (the protocol and the shared checks are in
:mod:`conceptfusion.perception.masks.base`):

* ``"rgbd"`` (default): :class:`conceptfusion.perception.masks.rgbd.RGBDProposer`, multi-scale graph
  segmentation on colour, depth and surface-normal discontinuities. Needs no weights.
  ``"rgbd:KEY=VALUE,KEY=VALUE"`` overrides settings of
  :class:`~conceptfusion.perception.masks.rgbd_config.RGBDProposerConfig`
  (``"rgbd:min_area_fraction=0.00025,fine_scale=15"``; a tuple setting takes ``a/b/c``).
* ``"sam:/path/to/checkpoint.pth"``: :class:`conceptfusion.perception.masks.sam.SamProposer`, SAM or
  MobileSAM's automatic mask generator with the official ConceptFusion settings (needs the
  ``segment_anything`` or ``mobile_sam`` package, imported only when the proposer is built, and a
  checkpoint).
* ``"gt"``: :class:`conceptfusion.perception.masks.base.GroundTruthProposer`, one mask per instance
  of a segmentation image. **Privileged**: it reads the simulator's segmentation, which a robot
  does not have.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from conceptfusion.names import unknown_name_error
from conceptfusion.perception.masks.base import GroundTruthProposer, MaskProposer
from conceptfusion.perception.masks.rgbd import RGBDProposer
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig
from conceptfusion.perception.masks.sam import SamProposer

__all__ = ["PROPOSERS", "make_proposer", "rgbd_config"]


def rgbd_config(arg: str) -> RGBDProposerConfig:
    """The :class:`~conceptfusion.perception.masks.rgbd_config.RGBDProposerConfig` of the settings
    ``"KEY=VALUE,KEY=VALUE"`` (the rest at their defaults), each value converted to its setting's
    type (``true``/``false`` for booleans, ``a/b/c`` for tuples).

    Raises:
        ValueError: an item is not ``KEY=VALUE``, a key is not a setting (naming them) or given
            twice, a value does not convert, or the settings are out of range (the config's checks).
    """
    types = {f.name: type(f.default) for f in dataclasses.fields(RGBDProposerConfig)}
    out: dict = {}
    for item in arg.split(","):
        key, sep, text = (part.strip() for part in item.partition("="))
        if not sep or not key or not text:
            raise ValueError(f"proposer 'rgbd': expected KEY=VALUE settings separated by commas, got {item!r} in 'rgbd:{arg}'")
        if key not in types:
            raise ValueError(f"proposer 'rgbd': {key!r} is not a setting; expected one of {', '.join(sorted(types))}")
        if key in out:
            raise ValueError(f"proposer 'rgbd': {key!r} given twice in 'rgbd:{arg}'")
        kind = types[key]
        try:
            if kind is bool:
                if text.lower() not in ("true", "false"):
                    raise ValueError(text)
                out[key] = text.lower() == "true"
            elif kind is tuple:
                out[key] = tuple(float(v) for v in text.split("/"))
            else:
                out[key] = kind(text)
        except ValueError:
            what = {bool: "true or false", tuple: "numbers separated by /"}.get(kind, f"a{'n' if kind is int else ''} {kind.__name__}")
            raise ValueError(f"proposer 'rgbd': {key} expects {what}, got {text!r}") from None
    return RGBDProposerConfig(**out)


def _make_rgbd(arg: str | None) -> MaskProposer:
    if not arg:
        return RGBDProposer()
    return RGBDProposer(rgbd_config(arg))


def _make_sam(arg: str | None) -> MaskProposer:
    if not arg:
        raise ValueError("proposer 'sam': expected a checkpoint path, as in 'sam:/path/to/sam_vit_h_4b8939.pth'")
    return SamProposer(arg)


def _make_gt(arg: str | None) -> MaskProposer:
    if arg:
        raise ValueError(f"proposer 'gt': takes no argument, got 'gt:{arg}'")
    return GroundTruthProposer()


PROPOSERS: dict[str, Callable[[str | None], MaskProposer]] = {
    "rgbd": _make_rgbd,
    "sam": _make_sam,
    "gt": _make_gt,
}
"""Proposer factories by name; each takes the text after ``name:`` (or ``None``)."""


def make_proposer(spec: str = "rgbd") -> MaskProposer:
    """Build a proposer from its registry spec: ``"rgbd"`` (or ``"rgbd:KEY=VALUE,..."``),
    ``"sam:/path/ckpt.pth"``, ``"gt"``.

    Unknown names raise ``ValueError`` listing the nearest registered names.
    """
    if not isinstance(spec, str):
        raise TypeError(f"spec: expected a proposer name such as 'rgbd', got {type(spec).__name__}")
    name, sep, arg = spec.strip().partition(":")
    name = name.lower()
    if name not in PROPOSERS:
        raise unknown_name_error("mask proposer", name, PROPOSERS, cutoff=0.3,
                                 listing=f"registered: {', '.join(sorted(PROPOSERS))}")
    return PROPOSERS[name](arg if sep else None)
