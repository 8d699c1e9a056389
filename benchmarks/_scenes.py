"""Synthetic inputs shared by the mapping benchmarks."""

from __future__ import annotations

import numpy as np

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.synthetic import Box, look_at, render_boxes


def room_boxes(seed: int = 0) -> list[Box]:
    """A 6 m x 4 m room: floor, four walls and 30 box objects of random colours and sizes."""
    rng = np.random.default_rng(seed)
    boxes = [
        Box("floor", (0.0, 0.0, -0.05), (6.0, 4.0, 0.1), (150, 150, 150)),
        Box("wall n", (0.0, 2.05, 1.25), (6.0, 0.1, 2.5), (200, 190, 170)),
        Box("wall s", (0.0, -2.05, 1.25), (6.0, 0.1, 2.5), (200, 190, 170)),
        Box("wall e", (3.05, 0.0, 1.25), (0.1, 4.0, 2.5), (190, 200, 170)),
        Box("wall w", (-3.05, 0.0, 1.25), (0.1, 4.0, 2.5), (190, 200, 170)),
    ]
    for i in range(30):
        size = rng.uniform(0.1, 0.6, 3)
        pos = (rng.uniform(-2.6, 2.6), rng.uniform(-1.6, 1.6), size[2] / 2)
        boxes.append(Box(f"object {i}", tuple(pos), tuple(size), tuple(int(c) for c in rng.integers(20, 235, 3))))
    return boxes


def room_trajectory(num: int) -> list[np.ndarray]:
    """A camera walking around the room at 1.4 m height, looking slightly down and outwards."""
    poses = []
    for t in np.linspace(0.0, 2 * np.pi, num, endpoint=False):
        eye = np.array([1.2 * np.cos(t), 0.7 * np.sin(t), 1.4])
        look = np.array([2.8 * np.cos(t + 0.9), 1.8 * np.sin(t + 0.9), 0.3])
        poses.append(look_at(eye, look))
    return poses


def frame_palette(instance_hw: np.ndarray, base_bd: np.ndarray, rng: np.random.Generator, grid: int = 4) -> PixelFeatures:
    """Pixel features like a mask proposer + CLIP would give: each instance split by a coarse
    image grid into parts, each part's feature its instance's base feature plus per-frame noise."""
    h, w = instance_hw.shape
    cell = (np.arange(h)[:, None] * grid // h) * grid + (np.arange(w)[None, :] * grid // w)
    key = np.where(instance_hw >= 0, instance_hw * grid * grid + cell, -1)
    uniq, inv = np.unique(key, return_inverse=True)
    inv = inv.reshape(h, w)
    inst = np.maximum(uniq, 0) // (grid * grid)
    pal = base_bd[inst] + 0.3 * rng.standard_normal((len(uniq), base_bd.shape[1]))
    pal /= np.linalg.norm(pal, axis=1, keepdims=True)
    index = np.where(uniq[inv] >= 0, inv, -1).astype(np.int32)
    return PixelFeatures(pal.astype(np.float32), index)


def render_sequence(num: int, height: int = 240, width: int = 320, dim: int = 512, seed: int = 0):
    """Pre-rendered frames: list of (rgb, depth, K, pose, PixelFeatures)."""
    rng = np.random.default_rng(seed)
    boxes = room_boxes(seed)
    base = rng.standard_normal((len(boxes), dim))
    K = intrinsics_from_fovy(60.0, width, height)
    out = []
    for pose in room_trajectory(num):
        f = render_boxes(boxes, K, pose, height, width)
        out.append((f.rgb, f.depth, K, pose, frame_palette(f.segmentation, base, rng)))
    return out
