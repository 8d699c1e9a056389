"""What every mask proposer shares: the protocol, the frame checks, and the ground-truth proposer.

A mask proposer turns one RGB-D frame into boolean region masks; the pixel-aligned features
(:func:`conceptfusion.perception.pipeline.frame_features`) embed a crop per mask. Proposals are
class-agnostic and may overlap (a part inside its object, an object inside a group), as
SAM's automatic generator's do. Every proposer has a ``privileged`` attribute so results built
on it can say so.

The proposers (:mod:`conceptfusion.perception.masks.rgbd`, :mod:`conceptfusion.perception.masks.sam`)
import this module; the registry (:mod:`conceptfusion.perception.masks.registry`) imports them.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from conceptfusion._checks import as_array
from conceptfusion.cameras import check_intrinsics
from conceptfusion.errors import DtypeError, ShapeError

__all__ = ["MaskProposer", "GroundTruthProposer", "check_frame", "empty_masks"]


@runtime_checkable
class MaskProposer(Protocol):
    """One RGB-D frame to class-agnostic, possibly overlapping boolean masks.

    ``privileged`` is ``True`` when the proposer reads information a robot does not have
    (ground-truth segmentation).
    """

    privileged: bool

    def propose(self, rgb_hw3: np.ndarray, depth_hw: np.ndarray, K_33: np.ndarray) -> np.ndarray:
        """Masks of one frame.

        Shape:
            ``rgb_hw3`` (H, W, 3) uint8, ``depth_hw`` (H, W) float metres along the optical
            axis (NaN, inf, <= 0 invalid), ``K_33`` (3, 3) -> ``masks_rhw`` (R, H, W) bool.
        """
        ...


def check_frame(rgb_hw3, depth_hw, K_33) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate one RGB-D frame at a proposer's boundary.

    Returns the image (uint8), the depth as float32 with every invalid value (NaN, inf,
    <= 0) replaced by NaN, and ``K`` as float64. Integer depth is refused with a hint to
    convert millimetres.

    Shape:
        (H, W, 3) uint8, (H, W) float, (3, 3) -> the same, depth float32.
    """
    rgb = as_array("rgb_hw3", rgb_hw3, shape=(None, None, 3), kinds="biuf")
    if rgb.dtype != np.uint8:
        raise DtypeError(f"rgb_hw3: expected uint8 RGB, got {rgb.dtype}")
    depth = as_array("depth_hw", depth_hw, shape=(None, None), kinds="fiu")
    if depth.dtype.kind != "f":
        raise DtypeError(f"depth_hw: expected float metres, got {depth.dtype} (convert millimetres with depth / 1000.0)")
    if depth.shape != rgb.shape[:2]:
        raise ShapeError(f"depth_hw: expected the image's size {rgb.shape[:2]}, got {depth.shape}")
    if rgb.shape[0] < 3 or rgb.shape[1] < 3:
        raise ShapeError(f"rgb_hw3: expected an image of at least 3x3 pixels, got {rgb.shape[:2]}")
    K = check_intrinsics(K_33)
    z = depth.astype(np.float32)
    with np.errstate(invalid="ignore"):
        z[~(np.isfinite(z) & (z > 0))] = np.nan
    return np.ascontiguousarray(rgb), z, K


def empty_masks(height: int, width: int) -> np.ndarray:
    """No masks for an (H, W) frame.

    Shape:
        returns (0, H, W) bool.
    """
    return np.zeros((0, height, width), bool)


class GroundTruthProposer:
    """One mask per instance id of a segmentation image (privileged).

    **Privileged.** It reads the simulator's instance segmentation; results built on it are
    an upper bound on perception and must say so (:attr:`privileged` is ``True``).

    Args:
        ignore_ids: instance ids that get no mask (e.g. floor and walls). Negative ids
            (background, nothing hit) never get one.
        min_area_px: instances covering fewer pixels are left out.
    """

    privileged = True

    def __init__(self, ignore_ids: tuple[int, ...] = (), *, min_area_px: int = 1) -> None:
        if min_area_px < 1:
            raise ValueError(f"min_area_px: expected at least 1, got {min_area_px}")
        self.ignore_ids = tuple(int(i) for i in ignore_ids)
        self.min_area_px = int(min_area_px)

    def from_segmentation(self, segmentation_hw) -> np.ndarray:
        """Masks of the instances in a segmentation image, in ascending id order.

        Shape:
            ``segmentation_hw`` (H, W) int -> (R, H, W) bool.
        """
        seg = as_array("segmentation_hw", segmentation_hw, shape=(None, None), kinds="iu").astype(np.int64)
        ids, counts = np.unique(seg, return_counts=True)
        keep = (ids >= 0) & (counts >= self.min_area_px) & ~np.isin(ids, self.ignore_ids)
        ids = ids[keep]
        if len(ids) == 0:
            return empty_masks(*seg.shape)
        return seg[None] == ids[:, None, None]

    def propose(self, rgb_hw3, depth_hw, K_33, *, segmentation_hw=None) -> np.ndarray:
        """Masks of one frame from its segmentation image (required keyword).

        Shape:
            (H, W, 3), (H, W), (3, 3), ``segmentation_hw`` (H, W) int -> (R, H, W) bool.
        """
        rgb, _, _ = check_frame(rgb_hw3, depth_hw, K_33)
        if segmentation_hw is None:
            raise ValueError(
                "segmentation_hw: the ground-truth proposer needs the frame's instance segmentation "
                "(propose(rgb, depth, K, segmentation_hw=...)); it is privileged information"
            )
        seg = np.asarray(segmentation_hw)
        if seg.shape != rgb.shape[:2]:
            raise ShapeError(f"segmentation_hw: expected the image's size {rgb.shape[:2]}, got {seg.shape}")
        return self.from_segmentation(seg)
