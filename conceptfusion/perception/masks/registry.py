"""Mask proposers by name: :data:`PROPOSERS` and :func:`make_proposer`.

Proposers, by registry name (the protocol and the shared checks are in
:mod:`conceptfusion.perception.masks.base`):

* ``"rgbd"`` (default): :class:`conceptfusion.perception.masks.rgbd.RGBDProposer`, multi-scale graph
  segmentation on colour, depth and surface-normal discontinuities. Needs no weights.
* ``"sam:/path/to/checkpoint.pth"``: :class:`conceptfusion.perception.masks.sam.SamProposer`, SAM or
  MobileSAM's automatic mask generator with the official ConceptFusion settings (needs the
  ``segment_anything`` or ``mobile_sam`` package, imported only when the proposer is built, and a
  checkpoint).
* ``"gt"``: :class:`conceptfusion.perception.masks.base.GroundTruthProposer`, one mask per instance
  of a segmentation image. **Privileged**: it reads the simulator's segmentation, which a robot
  does not have.
"""

from __future__ import annotations

from typing import Callable

from conceptfusion.names import unknown_name_error
from conceptfusion.perception.masks.base import GroundTruthProposer, MaskProposer
from conceptfusion.perception.masks.rgbd import RGBDProposer
from conceptfusion.perception.masks.sam import SamProposer

__all__ = ["PROPOSERS", "make_proposer"]


def _make_rgbd(arg: str | None) -> MaskProposer:
    if arg:
        raise ValueError(f"proposer 'rgbd': takes no argument, got 'rgbd:{arg}'")
    return RGBDProposer()


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
    """Build a proposer from its registry spec: ``"rgbd"``, ``"sam:/path/ckpt.pth"``, ``"gt"``.

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
