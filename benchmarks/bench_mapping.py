"""Mapping benchmarks: fusion throughput, memory per point, query latency.

    python benchmarks/bench_mapping.py [--frames 120] [--points 1000000] [--repeats 20]

Synthetic 6 m x 4 m room, 240x320 frames with 512-d palette features (about 130 distinct
features a frame) into a growing map. Targets (2-core CPU, idle): <= 256 bytes per point
including the shared feature bank; one text query (cosine scores) over 1M points <= 10 ms
median. Also reports what the compact feature store costs in query scores against exact
running means (eq. 1) of the same frames. Fusion by feature input on a MuJoCo orbit (the
fusion targets) is ``bench_fusion.py``.
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

from _scenes import render_sequence  # noqa: E402

from conceptfusion.perception.encoders import ColorNameEncoder  # noqa: E402
from conceptfusion.map.fusion import PointFusionMap  # noqa: E402
from conceptfusion.map.query import locate  # noqa: E402


def bench_fusion(frames: int, dim: int) -> PointFusionMap:
    seq = render_sequence(frames, dim=dim)
    fmap = PointFusionMap(dim)
    fmap.integrate(*seq[0])  # warm-up (first call allocates)
    times = []
    for rgb, depth, K, pose, feats in seq[1:]:
        t0 = time.perf_counter()
        fmap.integrate(rgb, depth, K, pose, feats)
        times.append(time.perf_counter() - t0)
    total = sum(times)
    print(f"fusion: {len(times)} frames 240x320, {dim}-d features -> {len(fmap):,} points")
    print(f"  {len(times) / total:.1f} frames/s (mean {1000 * total / len(times):.1f} ms, "
          f"median {1000 * statistics.median(times):.1f} ms, last 10 {1000 * statistics.mean(times[-10:]):.1f} ms)")
    return fmap


def bench_memory(fmap: PointFusionMap, frames: int, dim: int) -> None:
    n = len(fmap)
    live = fmap.nbytes()
    shared = fmap._store.nbytes(0)
    print(f"memory: {live / n:.0f} bytes/point held ({(live - shared) / n:.0f} per point + {shared / n:.0f} "
          f"for the shared feature bank of {fmap._store.bank.shape[0]:,} x {dim}; {live / 2**20:.1f} MiB "
          f"for {n:,} points)")
    # Cost of the compact store: the same frames fused with enough slots to be exact.
    exact = PointFusionMap(dim, slots=64)
    compact = PointFusionMap(dim)
    for args in render_sequence(frames, dim=dim):
        exact.integrate(*args)
        compact.integrate(*args)
    rng = np.random.default_rng(1)
    errs, agree = [], []
    for _ in range(20):
        q = compact._store.bank[rng.integers(len(compact._store.bank))]
        a, b = exact.scores(q), compact.scores(q)
        ok = np.isfinite(a)
        errs.append(np.abs(a[ok] - b[ok]))
        agree.append(np.mean((a[ok] > np.quantile(a[ok], 0.9)) == (b[ok] > np.quantile(b[ok], 0.9))))
    e = np.concatenate(errs)
    print(f"  compact vs exact running mean (20 queries): |score diff| mean {e.mean():.4f}, "
          f"p99 {np.quantile(e, 0.99):.4f}, max {e.max():.4f}; top-10% agreement {np.mean(agree):.3f}")


def synthetic_map(num_points: int, dim: int, bank: int = 20000, seed: int = 0) -> PointFusionMap:
    """A map state of the given size built directly (no rendering): random geometry, a
    random bank and 8 random entries per point with exact mixture norms. (The per-point
    Gram matrices, used only by fusion, are left zero.)"""
    rng = np.random.default_rng(seed)
    slots = 8
    bank_vecs = rng.standard_normal((bank, dim)).astype(np.float32)
    bank_vecs /= np.linalg.norm(bank_vecs, axis=1, keepdims=True)
    point_ids = rng.integers(0, bank, (num_points, slots)).astype(np.int32)
    point_w = rng.uniform(0.1, 1.0, (num_points, slots)).astype(np.float32)
    sq = np.empty(num_points)
    for s in range(0, num_points, 50000):
        sel = slice(s, s + 50000)
        f = np.einsum("mk,mkd->md", point_w[sel], bank_vecs[point_ids[sel]])
        sq[sel] = np.einsum("md,md->m", f, f)
    geo = np.zeros((num_points, 10), np.float32)
    geo[:, :3] = rng.uniform(-5, 5, (num_points, 3))
    geo[:, 5] = 1.0
    geo[:, 9] = 1.0
    header = {"feature_dim": dim, "num_points": num_points, "frames_integrated": 0,
              "config": {"dist_th": 0.05, "angle_th_deg": 20.0, "sigma": 0.6, "max_depth": None, "slots": slots}}
    arrays = {"geometry": geo, "feat_bank": bank_vecs, "feat_point_ids": point_ids, "feat_point_w": point_w,
              "feat_point_gram": np.zeros((num_points, slots * (slots + 1) // 2), np.float32), "feat_point_sq": sq}
    return PointFusionMap.from_state_dict(header, arrays)


def bench_query(num_points: int, dim: int, repeats: int) -> None:
    fmap = synthetic_map(num_points, dim)
    q = fmap._store.bank[3]
    fmap.scores(q)
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fmap.scores(q)
        t.append(time.perf_counter() - t0)
    print(f"query: cosine scores over {num_points:,} points ({dim}-d): median {1000 * statistics.median(t):.1f} ms, "
          f"max {1000 * max(t):.1f} ms")
    enc = ColorNameEncoder(dim=dim)
    qv = enc.encode_text(["red mug"])[0]
    neg = enc.encode_text(["object", "things", "stuff", "texture"])
    locate(fmap, qv, neg)  # warm-up: compiled kernels load on first use
    t = []
    for _ in range(5):
        t0 = time.perf_counter()
        locate(fmap, qv, neg)
        t.append(time.perf_counter() - t0)
    print(f"  full locate() (query + 4 negatives in one pass, regions): median {1000 * statistics.median(t):.0f} ms of 5")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--dim", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=20, help="timed queries")
    args = ap.parse_args()
    from _machine import probe_line

    print(probe_line())
    fmap = bench_fusion(args.frames, args.dim)
    bench_memory(fmap, min(args.frames, 60), args.dim)
    bench_query(args.points, args.dim, args.repeats)
    print(f"load average after: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
