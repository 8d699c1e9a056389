"""Settings of the RGB-D mask proposer (:class:`conceptfusion.perception.masks.rgbd.RGBDProposer`).

Apart from the proposer so that both of its halves, the pixel graph
(:mod:`conceptfusion.perception.masks.rgbd`) and the region selection
(:mod:`conceptfusion.perception.masks.regions`), read it without importing each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

__all__ = ["RGBDProposerConfig"]


@dataclass(frozen=True)
class RGBDProposerConfig:
    """Settings of :class:`~conceptfusion.perception.masks.rgbd.RGBDProposer` (defaults tuned for 240x320 household scenes)."""

    fine_scale: float = 60.0
    """Graph-segmentation scale ``k`` of the finest level (larger: bigger regions), given
    for a 240x320 frame and scaled with the pixel count."""
    merge_thresholds: tuple[float, ...] = (2.0, 4.0, 7.0)
    """Mean boundary weight below which adjacent regions merge, one coarser level each,
    ascending."""
    lightness_weight: float = 0.5
    """Weight of CIELAB lightness against the two chroma axes in the colour cue (shading
    changes lightness far more than chroma)."""
    color_scale: float = 6.0
    """CIELAB distance that costs as much as one unit of edge weight."""
    depth_tol: float = 0.01
    """Relative inverse-depth step (beyond the local slope) that costs one unit."""
    normal_tol_deg: float = 20.0
    """Normal angle in degrees that costs one unit."""
    convex_weight: float = 0.15
    """Factor on the normal cost of convex creases (where faces of one object meet);
    concave creases (where an object rests on a support) pay in full."""
    max_term: float = 6.0
    """Cap of each cue's cost, so no single cue dominates the ordering of strong edges."""
    blur_sigma: float = 0.8
    """Gaussian blur of the image before the colour cue, in pixels (0: none)."""
    depth_median_px: int = 1
    """Median filter of the depth before the geometric cues: 1 (off), 3 or 5 pixels. Off
    suits simulated (exact) depth, where filtering rounds object corners; use 5 for sensor
    depth (on synthetic frames with 0.5% depth noise it lifts mean best-IoU from ~0.65 to
    ~0.9)."""
    max_depth: float = math.inf
    """Depth beyond this (metres) counts as invalid."""
    min_area_fraction: float = 0.001
    """Smallest region, as a fraction of the frame's pixels; smaller regions are merged
    into a neighbour during segmentation and never proposed."""
    max_area_fraction: float = 0.6
    """Largest region proposed, as a fraction of the frame's pixels (background planes kept
    with ``keep_background_planes`` are exempt)."""
    min_valid_fraction: float = 0.5
    """Regions with a smaller fraction of valid depth pixels are dropped."""
    plane_tol_m: float = 0.01
    """Distance (metres) from a region's fitted plane within which a point is an inlier."""
    plane_inlier_fraction: float = 0.9
    """A region is planar when at least this fraction of its valid points are inliers."""
    background_min_fraction: float = 0.2
    """A planar region covering at least this fraction of the frame is a background plane."""
    background_min_extent_m: float = 1.0
    """A planar region spanning at least this many metres is a background plane."""
    background_overlap: float = 0.8
    """A region with at least this fraction of its pixels on background planes is dropped."""
    keep_background_planes: bool = False
    """Keep each background plane as one mask (its fragments are dropped either way)."""
    dedupe_iou: float = 0.9
    """A region with at least this IoU with an already proposed one is dropped."""
    max_masks: int = 64
    """At most this many masks per frame (the largest are kept)."""
    fixed_size_pixels: int = 0
    """0: ``fine_scale`` and ``min_area_fraction`` scale with the frame, so a frame of any size
    is cut into the same regions (a larger one in more detail). A pixel count (19200 for
    160x120): both hold the pixel sizes they give a frame of that many pixels, so a larger frame
    also resolves smaller things (a 320x240 frame then keeps regions down to 19 pixels instead of
    77). Frames of that size are segmented as with 0."""

    def __post_init__(self) -> None:
        if any(not (t > 0) for t in self.merge_thresholds):
            raise ValueError(f"merge_thresholds: expected positive values, got {self.merge_thresholds}")
        if list(self.merge_thresholds) != sorted(self.merge_thresholds):
            raise ValueError(f"merge_thresholds: expected ascending values, got {self.merge_thresholds}")
        if self.lightness_weight < 0:
            raise ValueError(f"lightness_weight: expected >= 0, got {self.lightness_weight}")
        positive = ("fine_scale", "color_scale", "depth_tol", "normal_tol_deg", "max_term", "max_depth", "plane_tol_m",
                    "background_min_extent_m")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: expected a positive value, got {getattr(self, name)}")
        if not 0 < self.normal_tol_deg < 180:
            raise ValueError(f"normal_tol_deg: expected a value in (0, 180), got {self.normal_tol_deg}")
        if self.depth_median_px not in (1, 3, 5):
            raise ValueError(f"depth_median_px: expected 1, 3 or 5, got {self.depth_median_px}")
        if self.blur_sigma < 0:
            raise ValueError(f"blur_sigma: expected >= 0, got {self.blur_sigma}")
        for f in fields(self):
            if f.name in ("min_area_fraction", "max_area_fraction", "min_valid_fraction", "background_min_fraction",
                          "background_overlap", "dedupe_iou", "plane_inlier_fraction"):
                v = getattr(self, f.name)
                if not 0 <= v <= 1:
                    raise ValueError(f"{f.name}: expected a fraction in [0, 1], got {v}")
        if self.min_area_fraction > self.max_area_fraction:
            raise ValueError(
                f"min_area_fraction, max_area_fraction: expected min <= max, got {self.min_area_fraction} > "
                f"{self.max_area_fraction}"
            )
        if isinstance(self.fixed_size_pixels, bool) or not isinstance(self.fixed_size_pixels, int) or self.fixed_size_pixels < 0:
            raise ValueError(f"fixed_size_pixels: expected an integer pixel count >= 0 (0: off), got {self.fixed_size_pixels!r}")
        if self.max_masks < 1:
            raise ValueError(f"max_masks: expected at least 1, got {self.max_masks}")
