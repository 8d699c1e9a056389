"""A bounded palette for dense features with no repeats (LSeg-style per-pixel encoders).

When every pixel has its own feature, an exact palette (:func:`conceptfusion.map.dense.palette_from_dense`)
is as large as the frame, and the map's shared bank would grow by ``H * W * d * 4`` bytes a
frame (157 MB at 240x320 with 512-d features). :func:`quantize_features` replaces the frame's
features by at most ``entries`` unit vectors found by spherical k-means, so the bank grows by
at most ``entries * d * 4`` bytes a frame (128 KiB for 64 entries of 512-d) while every map
point still holds 224 bytes plus geometry. The per-point mixtures then stay exact with
respect to the quantised features (see :mod:`conceptfusion.map.feature_store`).

Algorithm: ``sample`` non-zero pixels taken on a regular stride, normalised; k-means++
seeding (``seed``) and ``iterations`` Lloyd steps on cosine similarity (centroids are
normalised means) for three quarters of the entries; every pixel is assigned to its most
similar centroid; pixels left below cosine ``refine_below`` (regions the stride missed, such
as small objects) are fitted the same way with the remaining quarter and move to a new
centroid when it is more similar; finally each palette entry is the normalised mean of all
the pixels assigned to it. Working memory is bounded by ``sample * d`` plus
``chunk * entries`` floats besides the output; the input is read three times. The cost is
dominated by the assignment, ``H * W * entries * d`` multiply-adds (2.5 G for 240x320, 64
entries, 512-d): about 0.12 s of CPU a frame on this project's 2-core machine.

Measured error (``benchmarks/bench_fusion.py``: the first 12 frames of a 240x320 MuJoCo
orbit with 512-d synthetic per-pixel features, each pixel its region's direction plus a
smooth per-frame field plus noise, neighbouring pixels at cosine 0.978): with 64 entries,
``1 - cos`` between a pixel's exact and quantised feature is 0.012 on average (99th
percentile 0.021, worst pixel 0.040); query scores of the map fused from quantised features
differ from those of the exact map (every pixel its own bank row, 325 MiB of bank against
14 MiB, at 120x160) by 0.005 on average (99th percentile 0.019), and the top-10% point sets
agree on 96.5% of points. The input norms are dropped: palette rows are unit length.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from conceptfusion._checks import as_float_array
from conceptfusion.perception.features import PixelFeatures

__all__ = ["quantize_features"]


def quantize_features(
    feats_hwd,
    entries: int = 64,
    *,
    iterations: int = 4,
    sample: int = 2048,
    refine_below: float = 0.9,
    seed: int = 0,
    chunk: int = 16384,
) -> PixelFeatures:
    """Quantise dense per-pixel features to a palette of at most ``entries`` unit vectors.

    Args:
        feats_hwd: per-pixel features; all-zero rows mean "no feature" and keep index -1.
        entries: most palette rows (k of k-means).
        iterations: Lloyd steps on the sample.
        sample: pixels the centroids are fitted on (taken on a regular stride).
        refine_below: pixels whose cosine with their centroid is below this (regions the
            sample missed, such as small objects) are fitted again with the quarter of the
            entries kept for them.
        seed: seed of the k-means++ draws (same input and seed, same palette).
        chunk: pixels assigned per block (bounds the working memory).

    Shape:
        ``feats_hwd`` (H, W, d) float -> palette (P <= entries, d) float32 unit rows,
        index (H, W) int32.
    """
    f = as_float_array("feats_hwd", feats_hwd, shape=(None, None, None))
    checks = (("entries", entries, 1), ("iterations", iterations, 0), ("sample", sample, 1), ("chunk", chunk, 1))
    for name, v, lo in checks:
        if int(v) != v or v < lo:
            raise ValueError(f"{name}: expected an integer >= {lo}, got {v!r}")
    h, w, d = f.shape
    flat = f.reshape(h * w, d)
    if flat.dtype != np.float32 or not flat.flags.c_contiguous:
        flat = np.ascontiguousarray(flat, np.float32)
    norms = np.sqrt(_squared_norms(flat))
    if not np.all(np.isfinite(norms)):
        raise ValueError("feats_hwd: expected finite features, found NaN or inf")
    rows = np.flatnonzero(norms > 0)
    if rows.size == 0:
        return PixelFeatures(np.zeros((0, d), np.float32), np.full((h, w), -1, np.int32))
    rng = np.random.default_rng(seed)
    inv_norm = np.where(norms > 0, 1.0 / np.maximum(norms, 1e-300), 0.0)
    reserve = entries // 4
    centres = _kmeans(_unit_sample(flat, rows, inv_norm, sample), entries - reserve, iterations, rng)
    index = np.full(h * w, -1, np.int32)
    best = np.zeros(h * w, np.float64)  # cosine with the assigned centre
    _assign(flat, rows, inv_norm, centres, 0, index, best, chunk)
    far = rows[best[rows] < refine_below]
    if reserve and far.size:  # regions the sample missed (small objects) get their own entries
        extra = _kmeans(_unit_sample(flat, far, inv_norm, sample), reserve, iterations, rng)
        _assign(flat, far, inv_norm, extra, len(centres), index, best, chunk)
        centres = np.concatenate([centres, extra])
    sums = np.zeros((len(centres), d), np.float64)
    _accumulate(flat, index, inv_norm, sums)
    norm = np.linalg.norm(sums, axis=1)
    used = np.flatnonzero(norm > 0)
    remap = np.full(len(centres) + 1, -1, np.int32)
    remap[used] = np.arange(len(used), dtype=np.int32)
    palette = sums[used] / norm[used, None]
    return PixelFeatures(palette.astype(np.float32), remap[index].reshape(h, w))


def _unit_sample(flat_nd, rows, inv_norm, sample: int) -> np.ndarray:
    """Up to ``sample`` of ``rows``, evenly spaced, normalised, (S, d) float32."""
    picked = rows[np.linspace(0, rows.size - 1, min(sample, rows.size)).astype(np.int64)]
    return (flat_nd[picked] * inv_norm[picked, None]).astype(np.float32)


def _assign(flat_nd, rows, inv_norm, centres_kd, offset: int, index, best, chunk: int) -> None:
    """Give each of ``rows`` the most similar of ``centres`` (numbered from ``offset``) when it
    beats the cosine in ``best``; updates ``index`` and ``best`` in place."""
    contiguous = rows.size == 0 or rows[-1] - rows[0] + 1 == rows.size
    for s in range(0, rows.size, chunk):
        r = rows[s : s + chunk]
        x = flat_nd[r[0] : r[-1] + 1] if contiguous else flat_nd[r]
        sims = x @ centres_kd.T
        label = np.argmax(sims, axis=1)
        cos = sims[np.arange(len(r)), label] * inv_norm[r]
        better = cos > best[r]
        index[r[better]] = offset + label[better]
        best[r[better]] = cos[better]


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _squared_norms(x_nd):
    """Squared norm of each row, summed in float64 (no underflow for float32 input; the sum is
    reassociated so that it vectorises), (N,)."""
    out = np.empty(x_nd.shape[0], np.float64)
    for i in range(x_nd.shape[0]):
        acc = 0.0
        for k in range(x_nd.shape[1]):
            v = np.float64(x_nd[i, k])
            acc += v * v
        out[i] = acc
    return out


@njit(cache=True, nogil=True)
def _accumulate(x_nd, label_n, inv_norm_n, sums_pd):
    """``sums[label[i]] += x[i] * inv_norm[i]`` for the rows with ``inv_norm > 0`` (the others
    may carry label -1)."""
    for i in range(x_nd.shape[0]):
        a = inv_norm_n[i]
        if a > 0.0:
            row = sums_pd[label_n[i]]
            for k in range(x_nd.shape[1]):
                row[k] += x_nd[i, k] * a


def _kmeans(pts_sd: np.ndarray, k: int, iterations: int, rng: np.random.Generator) -> np.ndarray:
    """Spherical k-means of unit rows: k-means++ seeding, then Lloyd steps. Returns (k', d), k' <= k."""
    n = len(pts_sd)
    k = min(k, n)
    centres = np.empty((k, pts_sd.shape[1]), np.float32)
    centres[0] = pts_sd[rng.integers(n)]
    dist = np.maximum(1.0 - pts_sd @ centres[0], 0.0)
    chosen = 1
    for i in range(1, k):
        total = float(dist.sum())
        if total <= 0.0:  # fewer distinct directions than k
            break
        centres[i] = pts_sd[rng.choice(n, p=dist / total)]
        dist = np.minimum(dist, np.maximum(1.0 - pts_sd @ centres[i], 0.0))
        chosen += 1
    centres = centres[:chosen]
    for _ in range(iterations):
        label = np.argmax(pts_sd @ centres.T, axis=1).astype(np.int32)
        sums = np.zeros(centres.shape, np.float64)
        _accumulate(pts_sd, label, np.ones(n), sums)
        norm = np.linalg.norm(sums, axis=1)
        keep = norm > 0
        centres = (sums[keep] / norm[keep, None]).astype(np.float32)
    return centres
