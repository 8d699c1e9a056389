"""Fusion throughput by feature input, on a MuJoCo orbit, and the per-pixel (LSeg-style) path.

    python benchmarks/bench_fusion.py [--frames 60] [--repeats 3] [--per-pixel-frames 20]

A 60-frame orbit of shipped-generator tabletop scene 0 rendered by MuJoCo at 240x320 with
segmentation (objects and furniture labelled); each frame's 512-d features come from
``_scenes.frame_palette``: every labelled region split by a 4x4 image grid into parts, each
part its region's feature plus per-frame noise (about 17 distinct features a frame), as a
mask proposer plus CLIP gives. The same frames are fused three ways, each into a fresh map
(first frame excluded as warm-up; one untimed orbit before all, then the three inputs take turns), ``--repeats`` times, median reported:

* ``palette``: :class:`~conceptfusion.perception.features.PixelFeatures`;
* ``labels``: the pair ``(labels_hw, table_pd)``;
* ``dense``: the (240, 320, 512) float32 array (157 MB a frame), grouped by the map
  (the dense array is built before the timer starts).

Targets (2-core CPU, idle): palettes >= 150 frames/s, dense >= 60 frames/s, <= 256 B/point.

Per-pixel path: the same frames with synthetic LSeg-like features (every pixel distinct: its
region's direction, plus a smooth per-frame field of 4 low-frequency image modes, plus
per-pixel noise; neighbouring pixels at cosine about 0.98), quantised with
:func:`~conceptfusion.map.quantize.quantize_features` (64 entries) then fused. Reported:
quantisation time per frame, fusion throughput, ``1 - cos`` between exact and quantised pixel
features, and query-score differences between the quantised map and the exact map (every
pixel its own bank entry) built from the same frames at 120x160.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _scenes import frame_palette  # noqa: E402

from conceptfusion.map.fusion import PointFusionMap  # noqa: E402
from conceptfusion.map.quantize import quantize_features  # noqa: E402
from sim_envs.mujoco.scan import iter_views  # noqa: E402
from sim_envs.mujoco.scene import build_mujoco  # noqa: E402
from sim_envs.scenes.gen_tabletop import generate_tabletop  # noqa: E402
from sim_envs.scenes.trajectories import orbit_trajectory  # noqa: E402

DIM = 512


def render_orbit(frames: int, height: int = 240, width: int = 320):
    """(frames, segmentations): MuJoCo RGB-D frames of an orbit of tabletop scene 0."""
    scene = generate_tabletop(0)
    sim = build_mujoco(scene)
    views = list(iter_views(sim, orbit_trajectory(scene, frames), width, height, geom_labels=sim.geom_labels()))
    return views


def palettes(views, seed: int = 0):
    rng = np.random.default_rng(seed)
    base = rng.standard_normal((64, DIM))
    return [frame_palette(v.segmentation, base, rng) for v in views]


def time_fusion(views, feats, convert) -> tuple[float, PointFusionMap]:
    """Frames/s fusing ``views[1:]`` into a fresh map (frame 0 is the warm-up)."""
    fmap = PointFusionMap(DIM)
    v = views[0]
    fmap.integrate(v.rgb, v.depth, v.K, v.cam_to_world, convert(feats[0]))
    total = 0.0
    for v, f in zip(views[1:], feats[1:]):
        x = convert(f)
        t0 = time.perf_counter()
        fmap.integrate(v.rgb, v.depth, v.K, v.cam_to_world, x)
        total += time.perf_counter() - t0
    return (len(views) - 1) / total, fmap


def bench_inputs(views, feats, repeats: int) -> None:
    modes = {
        "palette": lambda pf: pf,
        "labels": lambda pf: (pf.index_hw, pf.palette_pd),
        "dense": lambda pf: pf.dense(),
    }
    print(f"fusion: {len(views) - 1} frames 240x320, {DIM}-d features, "
          f"{np.mean([len(f.palette_pd) for f in feats]):.0f} distinct features a frame on average")
    # One untimed orbit first, then the modes take turns in each repeat: a process's first
    # orbit runs slower (the allocator and the page tables grow with the first maps), and timing
    # one mode's repeats before the others' put that cost on whichever came first.
    time_fusion(views, feats, modes["palette"])
    rates: dict[str, list[float]] = {name: [] for name in modes}
    maps: dict[str, PointFusionMap] = {}
    for _ in range(repeats):
        for name, convert in modes.items():
            rate, maps[name] = time_fusion(views, feats, convert)
            rates[name].append(rate)
    for name in modes:
        fmap = maps[name]
        print(f"  {name:8s} {statistics.median(rates[name]):6.1f} frames/s median of {repeats} "
              f"({', '.join(f'{r:.1f}' for r in rates[name])}); {len(fmap):,} points, "
              f"{fmap.nbytes() / len(fmap):.0f} B/point")


def lseg_like(segmentation_hw: np.ndarray, base_kd: np.ndarray, rng: np.random.Generator,
              smooth: float = 0.5, noise: float = 0.15) -> np.ndarray:
    """Synthetic per-pixel features with no repeats: region direction + smooth field + noise, unit rows."""
    h, w = segmentation_hw.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    modes = np.stack([np.cos(np.pi * (a * xx / w + b * yy / h)) for a, b in ((1, 0), (0, 1), (1, 1), (2, 1))], -1)
    coef = rng.standard_normal((modes.shape[-1], DIM)).astype(np.float32) / np.sqrt(DIM * modes.shape[-1] / 2)
    f = base_kd[np.maximum(segmentation_hw, 0) % len(base_kd)] + smooth * (modes @ coef)
    f += (noise / np.sqrt(DIM)) * rng.standard_normal(f.shape, dtype=np.float32)
    f /= np.linalg.norm(f, axis=-1, keepdims=True)
    return f.astype(np.float32)


def bench_per_pixel(views, frames: int, entries: int = 64) -> None:
    rng = np.random.default_rng(1)
    base = rng.standard_normal((64, DIM)).astype(np.float32)
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    views = views[:frames]
    fmap = PointFusionMap(DIM)
    t_quant, t_fuse, errs, neigh = [], [], [], []
    for v in views:
        x = lseg_like(v.segmentation, base, rng)
        t0 = time.perf_counter()
        pf = quantize_features(x, entries)
        t1 = time.perf_counter()
        fmap.integrate(v.rgb, v.depth, v.K, v.cam_to_world, pf)
        t_fuse.append(time.perf_counter() - t1)
        t_quant.append(t1 - t0)
        errs.append(1.0 - np.einsum("hwd,hwd->hw", pf.dense(), x).ravel())
        neigh.append(np.einsum("hwd,hwd->hw", x[:, 1:], x[:, :-1]).mean())
    e = np.concatenate(errs)
    print(f"per-pixel features ({frames} frames 240x320, every pixel distinct, neighbour cosine "
          f"{np.mean(neigh):.3f}), quantised to {entries} entries:")
    print(f"  quantise {1000 * statistics.median(t_quant[1:]):.0f} ms/frame median, then fusion "
          f"{1000 * statistics.median(t_fuse[1:]):.1f} ms/frame; {len(fmap):,} points, "
          f"{fmap.nbytes() / len(fmap):.0f} B/point, bank {len(fmap._store.bank):,} x {DIM}")
    print(f"  1 - cos(exact, quantised) per pixel: mean {e.mean():.4f}, p99 {np.quantile(e, 0.99):.4f}, "
          f"max {e.max():.4f}")


def bench_per_pixel_map_error(frames: int, entries: int = 64) -> None:
    """Query scores of quantised vs exact maps, at 120x160 (the exact bank holds every pixel)."""
    views = render_orbit(frames, 120, 160)
    rng = np.random.default_rng(2)
    base = rng.standard_normal((64, DIM)).astype(np.float32)
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    exact, quant = PointFusionMap(DIM), PointFusionMap(DIM)
    import logging

    logging.getLogger("conceptfusion.map.fusion").setLevel(logging.ERROR)  # the exact map warns, by design
    for v in views:
        x = lseg_like(v.segmentation, base, rng)
        exact.integrate(v.rgb, v.depth, v.K, v.cam_to_world, x)
        quant.integrate(v.rgb, v.depth, v.K, v.cam_to_world, quantize_features(x, entries))
    diffs, agree = [], []
    for k in range(20):  # queries: the region directions, and random mixtures of them
        q = base[k % len(base)] if k < 10 else rng.standard_normal(3) @ base[rng.integers(0, 10, 3)]
        a, b = exact.scores(q), quant.scores(q)
        ok = np.isfinite(a) & np.isfinite(b)
        diffs.append(np.abs(a[ok] - b[ok]))
        agree.append(np.mean((a[ok] > np.quantile(a[ok], 0.9)) == (b[ok] > np.quantile(b[ok], 0.9))))
    d = np.concatenate(diffs)
    print(f"  fused map ({frames} frames at 120x160, exact bank {len(exact._store.bank):,} rows = "
          f"{exact.nbytes() / 2**20:.0f} MiB vs quantised {quant.nbytes() / 2**20:.0f} MiB): |score diff| "
          f"mean {d.mean():.4f}, p99 {np.quantile(d, 0.99):.4f}; top-10% agreement {np.mean(agree):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--per-pixel-frames", type=int, default=20, help="0 skips the per-pixel path")
    args = ap.parse_args()
    from _machine import probe_line

    print(probe_line())
    views = render_orbit(args.frames)
    bench_inputs(views, palettes(views), args.repeats)
    if args.per_pixel_frames:
        bench_per_pixel(views, min(args.per_pixel_frames, len(views)))
        bench_per_pixel_map_error(min(args.per_pixel_frames, 12))
    print(f"load average after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
