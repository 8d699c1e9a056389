"""Procedural material textures: small images made with numpy, written once as PNG.

One image per (material, colour): the colour modulated by the material's pattern (wood grain,
brushed streaks, fabric weave, paper fibre, glass highlights, ...). The noise is seeded from the
names, so the same pair always gives the same pixels. Both simulators map the image with the
mesh's texture coordinates, so an instance looks the same in MuJoCo and PyBullet.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from conceptfusion.errors import SimError
from conceptfusion.io_utils import atomic_write_bytes
from conceptfusion.names import did_you_mean
from sim_envs.assets.library.palette import MATERIALS, PALETTE
from sim_envs.assets.meshes import cache_dir

__all__ = ["texture_image", "texture_path", "TEXTURE_SIZE"]

TEXTURE_SIZE = 128
"""Pixels a side."""

_VERSION = "2"


def _smooth_noise(rng: np.random.Generator, size: int, cells: tuple[int, int]) -> np.ndarray:
    """Value noise in [-1, 1]: a (cells) grid of random values, bicubically upsampled."""
    import cv2

    grid = rng.uniform(-1.0, 1.0, cells).astype(np.float32)
    return cv2.resize(grid, (size, size), interpolation=cv2.INTER_CUBIC).astype(np.float64)


def _pattern(kind: str, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, n) shading in about [-1, 1]; rows are v (up the object), columns u (round it)."""
    y, x = np.mgrid[0:n, 0:n] / n
    if kind == "grain":  # rings along v, warped by noise
        warp = _smooth_noise(rng, n, (4, 4))
        return np.sin(2 * np.pi * (5 * x + 0.8 * warp)) * 0.6 + 0.4 * _smooth_noise(rng, n, (32, 4))
    if kind == "brushed":  # fine streaks along u
        return 0.6 * _smooth_noise(rng, n, (n, 4)) + 0.4 * np.cos(2 * np.pi * y)
    if kind == "glaze":
        return 0.6 * _smooth_noise(rng, n, (6, 6)) + 0.4 * (rng.random((n, n)) > 0.995)
    if kind == "flat":
        return _smooth_noise(rng, n, (4, 4))
    if kind == "weave":
        return 0.5 * np.sign(np.sin(2 * np.pi * 24 * x)) * np.sign(np.sin(2 * np.pi * 24 * y)) + 0.5 * _smooth_noise(rng, n, (16, 16))
    if kind == "fibre":
        return 0.7 * _smooth_noise(rng, n, (48, 12)) + 0.3 * rng.uniform(-1, 1, (n, n))
    if kind == "streak":  # soft vertical highlights, as a window reflected in glass
        return np.clip(2.5 * np.exp(-((x - 0.3) ** 2) / 0.002) + 1.5 * np.exp(-((x - 0.7) ** 2) / 0.0008), 0, 1.5) - 0.2
    if kind == "speckle":
        return 0.5 * rng.uniform(-1, 1, (n, n)) + 0.5 * _smooth_noise(rng, n, (16, 16))
    if kind == "mottle":
        return 0.8 * _smooth_noise(rng, n, (10, 10)) + 0.2 * rng.uniform(-1, 1, (n, n))
    if kind == "soft":
        return 0.6 * (y - 0.5) + 0.4 * _smooth_noise(rng, n, (3, 3))
    raise SimError(f"texture pattern: unknown pattern {kind!r}")


def texture_image(material: str, color: str, size: int = TEXTURE_SIZE) -> np.ndarray:
    """The texture of ``material`` in ``color`` as an RGB image.

    Shape:
        returns (size, size, 3) uint8, row 0 at v = 1 (image convention: top row first).
    """
    if material not in MATERIALS:
        raise SimError(f"texture: unknown material {material!r}" + did_you_mean(material, MATERIALS))
    if color not in PALETTE:
        raise SimError(f"texture: unknown colour {color!r}" + did_you_mean(color, PALETTE))
    spec = MATERIALS[material]
    seed = int.from_bytes(hashlib.sha256(f"{material}|{color}".encode()).digest()[:8], "little")
    shade = _pattern(spec.pattern, np.random.default_rng(seed), size)
    rgb = np.asarray(PALETTE[color], np.float64)
    img = rgb[None, None, :] * (1.0 + spec.contrast * shade[..., None])
    if spec.pattern == "streak":  # highlights go white, not just brighter
        img = img + 0.25 * np.clip(shade, 0, None)[..., None]
    return (np.clip(img, 0, 1)[::-1] * 255).round().astype(np.uint8)


def texture_path(material: str, color: str) -> Path:
    """Path of the PNG of :func:`texture_image` in the asset cache (written on first use)."""
    slug = color.replace(" ", "_")
    out = cache_dir() / "library" / "textures" / f"{material}_{slug}_v{_VERSION}_{TEXTURE_SIZE}.png"
    if out.exists():
        return out
    import cv2

    ok, buf = cv2.imencode(".png", texture_image(material, color)[..., ::-1])
    if not ok:
        raise SimError(f"could not encode the texture {material}/{color} as PNG")
    atomic_write_bytes(out, buf.tobytes())
    return out
