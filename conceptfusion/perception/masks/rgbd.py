"""The default mask proposer: multi-scale graph segmentation of RGB-D frames.

Needs no weights. Every 4-neighbour pixel pair gets an edge weight that adds three cues,
each capped at ``max_term``:

* **colour**: CIELAB distance of the (lightly blurred) image, over ``color_scale``;
* **depth**: how far the step in inverse depth between the two pixels departs from the
  steps just before and after it, relative to the inverse depth. Inverse depth is affine
  in the pixel coordinates on any plane, so a slanted floor costs nothing while an
  occluding edge costs a lot; over ``depth_tol``;
* **normal**: ``1 - cos`` of the angle between the two surface normals, over
  ``1 - cos(normal_tol_deg)``. Concave creases (normals converging: where a box stands on
  a table) pay in full; convex ones (normals diverging: two faces of one box) pay only
  ``convex_weight`` of it, the local convexity cue of RGB-D object segmentation.

A pixel pair with one invalid depth gets the full geometric cost; two invalid pixels
only the colour cost. Normals come from one-sided differences on the side of the smaller
depth change, so pixels next to an occluding edge keep their own surface's normal.

Segmentation has levels. Level 0 is graph-based segmentation (Felzenszwalb and
Huttenlocher, 2004) at scale ``fine_scale``: faces of objects, patches of texture. Each
further level merges adjacent regions of the previous one whose boundary edges have a mean
weight at most the next of ``merge_thresholds`` (a mean over a whole boundary does not
leak through the few weak edges that pixel-level merging does). The levels are nested: a
box face at level 0 lies inside its box at a coarser level, so proposals overlap as SAM's
do (part and object).

Regions are then filtered: too small, too large, mostly invalid depth, near-duplicates of
a region already proposed (IoU at least ``dedupe_iou``), and **background planes**. A
region is a background plane when its points fit a plane (``plane_inlier_fraction`` of
them within ``plane_tol_m``) and it covers at least ``background_min_fraction`` of the
frame or spans at least ``background_min_extent_m``: floors, walls, table tops. A plane's
crop is most of the frame, so its embedding adds little beyond the global one, while its
pixels under object masks would dilute them. Every pixel within ``plane_tol_m`` of a
background plane is background, and regions with at least ``background_overlap`` of
their pixels there are dropped too (floor patches cut off by the table, the table top
with an object merged in). With ``keep_background_planes=True`` each background plane is
instead proposed as exactly one mask (its pixels within tolerance), and the fragments
still go. Flat things lying within ``plane_tol_m`` of a background plane (a sheet of paper
on a table) are lost with it.

Output order: by area, largest first; ties by scale, then by first pixel in raster order.
The result is a pure function of the inputs (no randomness, no threading).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections import OrderedDict
from dataclasses import fields

import cv2
import numpy as np

from conceptfusion.cameras import backproject
from conceptfusion.perception.masks.base import check_frame, empty_masks
from conceptfusion.perception.masks.pixel_graph import edge_aware_normals, edge_weights, stable_order
from conceptfusion.perception.masks.regions import felzenszwalb, merge_levels, select_regions
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig

__all__ = ["RGBDProposer", "frame_config"]

_REF_PIXELS = 240 * 320


class RGBDProposer:
    """Class-agnostic, overlapping masks from colour, depth and normal discontinuities.

    See the module docstring for the method. Deterministic; no weights.

    Args:
        config: settings (:class:`conceptfusion.perception.masks.rgbd_config.RGBDProposerConfig`);
            keyword overrides are applied on top.
    """

    privileged = False

    cache_frames = 4
    """The last frames whose masks are remembered (keyed by the settings and the frame's
    pixels, depth and intrinsics): a robot standing still proposes once. Exact: the result is
    a pure function of the settings and the frame."""

    def __init__(self, config: RGBDProposerConfig | None = None, **overrides) -> None:
        base = config if config is not None else RGBDProposerConfig()
        if not isinstance(base, RGBDProposerConfig):
            raise TypeError(f"config: expected RGBDProposerConfig, got {type(base).__name__}")
        self.config = RGBDProposerConfig(**{**{f.name: getattr(base, f.name) for f in fields(base)}, **overrides})
        self._recent: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()

    def propose(self, rgb_hw3, depth_hw, K_33) -> np.ndarray:
        """Masks of one frame (see :class:`conceptfusion.perception.masks.base.MaskProposer`).

        Shape:
            ``rgb_hw3`` (H, W, 3) uint8, ``depth_hw`` (H, W) float, ``K_33`` (3, 3)
            -> ``masks_rhw`` (R, H, W) bool, R <= ``max_masks``.
        """
        masks, _ = self.segment(rgb_hw3, depth_hw, K_33)
        return masks

    def segment(self, rgb_hw3, depth_hw, K_33) -> tuple[np.ndarray, np.ndarray]:
        """Masks and the segmentation level each came from (0: finest; see the module docstring).

        Shape:
            as :meth:`propose` -> ``masks_rhw`` (R, H, W) bool, ``level_r`` (R,) int64.
        """
        rgb, depth, K = check_frame(rgb_hw3, depth_hw, K_33)
        digest = hashlib.blake2b(repr(self.config).encode(), digest_size=20)
        for arr in (rgb, depth, K):
            digest.update(str(arr.shape).encode())
            digest.update(np.ascontiguousarray(arr).data)
        key = digest.digest()
        if key in self._recent:
            self._recent.move_to_end(key)
        else:
            self._recent[key] = self._segment(rgb, depth, K)
            while len(self._recent) > self.cache_frames:
                self._recent.popitem(last=False)
        masks, level = self._recent[key]
        return masks.copy(), level.copy()

    def _segment(self, rgb, depth, K) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`segment` of a checked frame (uint8 image, float32 depth with NaN where invalid, float64 K)."""
        h, w = depth.shape
        n = h * w
        cfg = frame_config(self.config, n)
        with np.errstate(invalid="ignore"):
            depth = np.where(depth <= cfg.max_depth, depth, np.nan).astype(np.float32)
        if cfg.depth_median_px > 1:
            smooth = cv2.medianBlur(np.nan_to_num(depth, nan=0.0), cfg.depth_median_px)
            depth = np.where(np.isfinite(depth) & (smooth > 0), smooth, np.nan).astype(np.float32)
        valid = np.isfinite(depth)
        if not valid.any():
            return empty_masks(h, w), np.zeros(0, np.int64)
        vertex = backproject(depth, K)
        src, dst, weight = _edges(rgb, depth, vertex, edge_aware_normals(vertex), valid, cfg)
        order = stable_order(weight)
        k = cfg.fine_scale * (n / _REF_PIXELS)
        min_size = max(1, int(round(cfg.min_area_fraction * n)))
        fine, count = felzenszwalb(src[order], dst[order], weight[order], n, k, min_size)
        labels, counts = merge_levels(fine, count, src, dst, weight, cfg.merge_thresholds)
        return select_regions(labels, counts, vertex.reshape(n, 3), valid.reshape(n), cfg, h, w)


def frame_config(config: RGBDProposerConfig, pixels: int) -> RGBDProposerConfig:
    """The settings a frame of ``pixels`` pixels is segmented with: ``config`` itself, or with
    ``config.fixed_size_pixels`` its ``fine_scale`` and ``min_area_fraction`` rescaled so that
    the regions they make keep the pixel sizes they have in a frame of that many pixels."""
    fixed = config.fixed_size_pixels
    if not fixed or fixed == pixels:
        return config
    factor = fixed / pixels
    return dataclasses.replace(config, fine_scale=config.fine_scale * factor,
                               min_area_fraction=min(config.min_area_fraction * factor, config.max_area_fraction))


def _edges(rgb, depth, vertex, normals, valid, cfg: RGBDProposerConfig):
    """Right and down 4-neighbour edges with their combined weights (the colour cue's CIELAB
    image and the inverse depth here, the per-edge costs in
    :func:`~conceptfusion.perception.masks.pixel_graph.edge_weights`).

    Shape:
        (H, W, 3), (H, W), vertex and normals (H, W, 3), (H, W) -> src (E,), dst (E,) int64,
        weight (E,) float32.
    """
    img = rgb.astype(np.float32) / 255.0
    if cfg.blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    inv = np.where(valid, 1.0 / np.where(valid, depth, 1.0), np.nan).astype(np.float32)
    return edge_weights(lab, inv, vertex, normals, valid, cfg)
