"""2D IoU of text queries with the embedded tower on rendered tabletop scenes, and its speed.

For each of ``--scenes`` tabletop scenes never used in training (seeds from 95000), a few
random views are rendered (240x320). Each view gets pixel-aligned features
(:func:`conceptfusion.perception.pipeline.frame_features`: global embedding, one crop per mask, the
paper's mixing) from masks of the RGB-D proposer and, as an upper bound on the masks, of the
privileged ground-truth proposer. Every visible object (at least ``--min-px`` pixels) is
queried by its name ("red mug"), and the answer is compared with the object's ground-truth
mask:

* ``relative``: pixels whose (s+1)/2 score, min-max normalised over the frame, is at least
  0.6 (the paper's text threshold);
* ``best mask``: the pixels of the single best-scoring palette entry (one mask or one
  overlap of masks).

Reported: mean 2D IoU over objects, the fraction of objects whose best mask overlaps them
with IoU >= 0.5, and the time per frame of proposals + features.

    python benchmarks/bench_tower.py [--scenes 10] [--views 3] [--encoder embedded]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def score_view(feats, seg_hw: np.ndarray, names: tuple[str, ...], encoder, min_px: int) -> list[tuple[float, float]]:
    """(relative-threshold IoU, best-mask IoU) of every visible object's name query in one view."""
    out = []
    valid = feats.index_hw >= 0
    for obj in np.unique(seg_hw[seg_hw >= 0]):
        gt = seg_hw == obj
        if gt.sum() < min_px:
            continue
        q = encoder.encode_text([names[obj]])[0]
        pal = feats.palette_pd @ q
        s = np.where(valid, pal[np.maximum(feats.index_hw, 0)], np.nan)
        r = (s + 1) / 2
        lo, hi = np.nanmin(r), np.nanmax(r)
        rel = (r - lo) / max(hi - lo, 1e-12)
        sel_rel = np.nan_to_num(rel, nan=0.0) >= 0.6
        sel_best = feats.index_hw == int(np.argmax(pal))
        out.append((_iou(sel_rel, gt), _iou(sel_best, gt)))
    return out


def main() -> None:
    import torch

    torch.set_num_threads(2)
    from conceptfusion.perception.registry import make_encoder
    from conceptfusion.perception.masks.registry import make_proposer
    from conceptfusion.perception.pipeline import frame_features
    from tower_training.views import ViewConfig, random_tabletop_views

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=10)
    p.add_argument("--views", type=int, default=3)
    p.add_argument("--encoder", default="embedded")
    p.add_argument("--min-px", type=int, default=150)
    args = p.parse_args()
    encoder = make_encoder(args.encoder)
    proposers = {"rgbd": make_proposer("rgbd"), "gt (privileged)": make_proposer("gt")}
    results = {k: [] for k in proposers}
    times = {k: [] for k in proposers}
    n_masks = []
    views = random_tabletop_views(range(95_000, 95_000 + args.scenes), args.views, np.random.default_rng(0),
                                  ViewConfig(width=320, height=240))
    encoder.encode_image([np.zeros((64, 64, 3), np.uint8)])  # warm-up
    for v in views:
        f = v.frame
        for key, prop in proposers.items():
            t0 = time.perf_counter()
            if prop.privileged:
                masks = prop.propose(f.rgb, f.depth, f.K, segmentation_hw=f.segmentation)
            else:
                masks = prop.propose(f.rgb, f.depth, f.K)
                n_masks.append(len(masks))
            feats = frame_features(f.rgb, masks, encoder)
            times[key].append(time.perf_counter() - t0)
            results[key] += score_view(feats, f.segmentation, v.object_names, encoder, args.min_px)
    print(f"encoder {args.encoder}: {args.scenes} held-out tabletop scenes x {args.views} views (240x320), "
          f"{len(results['rgbd'])} object queries; rgbd proposer {np.mean(n_masks):.1f} masks/frame")
    print(f"{'proposer':<18} {'IoU relative>=0.6':>18} {'IoU best mask':>14} {'best mask IoU>=0.5':>19} {'ms/frame':>9}")
    for key, r in results.items():
        a = np.asarray(r)
        print(f"{key:<18} {a[:, 0].mean():>18.3f} {a[:, 1].mean():>14.3f} {np.mean(a[:, 1] >= 0.5):>19.3f} "
              f"{1000 * np.median(times[key]):>9.0f}")


if __name__ == "__main__":
    main()
