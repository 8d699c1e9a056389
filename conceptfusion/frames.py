"""The one posed RGB-D frame type, shared by the environments, the map suites, the tower's
training data, the demo and the benchmarks.

Conventions (see :mod:`conceptfusion.cameras`): OpenCV camera frame (x right, y down, z
forward), ``cam_to_world`` a 4x4 float64 camera-to-world matrix, metric depth along the optical
axis with ``inf`` (or NaN, or <= 0) where nothing valid was measured.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from conceptfusion._checks import as_array

__all__ = ["RGBDFrame"]


@dataclass(frozen=True, kw_only=True)
class RGBDFrame:
    """One posed RGB-D frame, optionally with a label image.

    Shape:
        ``rgb`` (H, W, 3) uint8; ``depth`` (H, W) float32 metres; ``K`` (3, 3);
        ``cam_to_world`` (4, 4); ``segmentation`` (H, W) int32 or None.

    Example::

        from conceptfusion import RGBDFrame

        frame = RGBDFrame(rgb=rgb_hw3, depth=depth_hw, K=K_33, cam_to_world=np.eye(4))
        frame = RGBDFrame.from_observation(obs)   # an environment's observation dict, checked
    """

    rgb: np.ndarray
    depth: np.ndarray
    K: np.ndarray
    cam_to_world: np.ndarray
    segmentation: np.ndarray | None = None
    """Ground-truth label per pixel (an object or part index, -1: none), when the source knows
    it (a simulator). **Privileged**: a robot has no such image; only privileged perception
    (the oracle) and scoring code may read it."""

    def observation(self) -> dict:
        """The frame as a robot sees it: ``rgb``, ``depth``, ``K``, ``cam_to_world`` (no labels)."""
        return {"rgb": self.rgb, "depth": self.depth, "K": self.K, "cam_to_world": self.cam_to_world}

    @classmethod
    def from_observation(cls, observation: Mapping, segmentation: np.ndarray | None = None) -> "RGBDFrame":
        """The posed frame in an observation dict (``rgb``, ``depth``, ``K``, ``cam_to_world``),
        checked: ``ValueError``/``TypeError`` naming the missing key or the bad array."""
        if not isinstance(observation, Mapping):
            raise TypeError(f"observation: expected a mapping with rgb, depth, K, cam_to_world, got {type(observation).__name__}")
        missing = [k for k in ("rgb", "depth", "K", "cam_to_world") if k not in observation]
        if missing:
            raise ValueError(f"observation: missing {', '.join(missing)} (expected rgb, depth, K, cam_to_world)")
        rgb = as_array("rgb", np.asarray(observation["rgb"]), shape=(None, None, 3))
        depth = as_array("depth", np.asarray(observation["depth"]), shape=rgb.shape[:2], kinds="f")
        K = as_array("K", np.asarray(observation["K"]), shape=(3, 3))
        pose = as_array("cam_to_world", np.asarray(observation["cam_to_world"]), shape=(4, 4))
        seg = None if segmentation is None else as_array("segmentation", np.asarray(segmentation), shape=rgb.shape[:2], kinds="iu")
        return cls(rgb=rgb, depth=depth, K=K, cam_to_world=pose, segmentation=seg)

    @property
    def shape(self) -> tuple[int, int]:
        """Image size ``(H, W)``."""
        return int(self.depth.shape[0]), int(self.depth.shape[1])
