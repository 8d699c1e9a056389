"""The v2 training world: crops of object-library arrangements, split by the one split file.

Three sets of views, each from its own seed role of :func:`sim_envs.scenes.splits.splits`:

* **train**: ``tower_train`` seeds, arrangements of TRAIN instances only;
* **val**: ``tower_val`` seeds, arrangements of VAL instances only (held-out instances of
  train categories and the VAL categories), for model selection;
* **test**: ``evaluation`` seeds, arrangements of TRAIN and TEST instances: seen instances from
  unseen views, held-out instances and held-out (TEST) categories. Rendered with the rest (the
  crops are cached together) but read only by :func:`tower_training.evaluate_v2.evaluate_crops_v2`
  after training and model selection.

Crops are cut as in v1 (:func:`tower_training.data.build_crop_data`: ground-truth boxes with
random padding, matched RGB-D proposer masks, background masks, whole frames); labels index
:func:`library_classes` (every instance id, then background, then scene).
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import asdict, dataclass
from itertools import chain
from pathlib import Path

import numpy as np

from sim_envs.assets.library import catalogue
from sim_envs.scenes.splits import Splits, splits
from tower_training.captions import CaptionBank, Caption, caption_bank, instance_captions
from tower_training.data import BACKGROUND_CLASS, SCENE_CLASS, CropConfig, CropData, ObjectClass

__all__ = ["DataConfigV2", "SETS", "library_classes", "train_caption_bank", "render_crop_data_v2", "split_summary"]

logger = logging.getLogger(__name__)

SETS = {"train": "tower_train", "val": "tower_val", "test": "evaluation"}
"""View set -> the seed role its scenes come from."""


@dataclass(frozen=True)
class DataConfigV2:
    """How many library arrangements of each set are rendered, and how."""

    train_scenes: int = 500
    """Training arrangements (first seeds of ``tower_train``)."""
    val_scenes: int = 60
    """Validation arrangements (first seeds of ``tower_val``)."""
    test_scenes: int = 100
    """Test arrangements (first seeds of ``evaluation``)."""
    views_per_scene: int = 4
    """Random views per arrangement."""
    width: int = 320
    height: int = 240
    seed: int = 0
    """Seeds the viewpoints, lights and crop jitter (the arrangements follow from their seeds)."""
    crops: CropConfig = CropConfig()
    """How crops are cut."""

    def seeds(self, which: str, split: Splits) -> list[int]:
        """The scene seeds of one set (``"train"``, ``"val"``, ``"test"``)."""
        n = {"train": self.train_scenes, "val": self.val_scenes, "test": self.test_scenes}[which]
        return split.seeds_of(SETS[which], n)


def library_classes() -> list[ObjectClass]:
    """One class per library instance (name: the instance id), catalogue order; phrases are its
    captions, category and colour filled in."""
    cat = catalogue()
    return [ObjectClass(i.id, tuple(c.text for c in instance_captions(i, cat)), i.category, i.color)
            for i in cat.instances.values()]


def train_caption_bank(split: Splits | None = None) -> CaptionBank:
    """The captions of TRAIN instances, plus the background and scene classes' phrases.

    Classes: TRAIN instance ids (sorted), then ``BACKGROUND_CLASS.name``, ``SCENE_CLASS.name``.
    No text of a VAL or TEST category name enters the bank unless a train category shares it.
    """
    split = splits() if split is None else split
    cat = catalogue()
    pairs = [(iid, instance_captions(cat.instances[iid], cat)) for iid in split.instances_of("train")]
    for special in (BACKGROUND_CLASS, SCENE_CLASS):
        pairs.append((special.name, [Caption(p, "background" if special is BACKGROUND_CLASS else "scene")
                                     for p in special.phrases]))
    return caption_bank(pairs)


def split_summary(split: Splits | None = None) -> dict:
    """Categories and instance counts per role (for ``tower.json``)."""
    split = splits() if split is None else split
    return {
        "file": "scenes/splits-v1.json",
        "categories": {r: split.categories_of(r) for r in ("train", "val", "test")},
        "instances": {r: len(split.instances_of(r)) for r in ("train", "val", "test")},
        "seeds": {k: list(v) for k, v in split.seeds.items()},
    }


def _cache_path(cache_dir: Path, config: DataConfigV2) -> Path:
    from sim_envs.assets.library import catalogue_hash

    key_src = json.dumps({"config": asdict(config), "catalogue": catalogue_hash()}, sort_keys=True)
    return cache_dir / f"tower_crops_v2_{hashlib.sha256(key_src.encode()).hexdigest()[:16]}.npz"


def render_crop_data_v2(config: DataConfigV2, cache_dir: Path | None = None, *, proposer=None) -> CropData:
    """Render (or load from the cache) the crops of the train, val and test arrangements.

    Labels index ``library_classes() + [BACKGROUND_CLASS, SCENE_CLASS]``; ``seeds`` tell the sets
    apart (:meth:`DataConfigV2.seeds`).

    Args:
        proposer: mask proposer for proposer/background crops (default: ``make_proposer("rgbd")``).
    """
    if cache_dir is not None:
        path = _cache_path(Path(cache_dir), config)
        if path.is_file():
            logger.info("crop data from cache %s", path)
            return CropData.load(path)
    from conceptfusion.perception.masks.registry import make_proposer
    from tower_training.data import build_crop_data
    from tower_training.library_views import pool_for_seed_role, random_library_views
    from tower_training.views import ViewConfig

    split = splits()
    classes = library_classes() + [BACKGROUND_CLASS, SCENE_CLASS]
    rng = np.random.default_rng(config.seed)
    vc = ViewConfig(width=config.width, height=config.height)
    views = chain.from_iterable(
        random_library_views(config.seeds(which, split), pool_for_seed_role(split, role), config.views_per_scene, rng, vc)
        for which, role in SETS.items())
    data = build_crop_data(views, classes, rng, proposer=make_proposer("rgbd") if proposer is None else proposer,
                           config=config.crops)
    if cache_dir is not None:
        data.save(path)
        logger.info("crop data cached at %s", path)
    return data


if __name__ == "__main__":  # render the default data into the default cache
    import os
    import sys

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    cache = Path(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.expanduser("~/.cache"), "conceptfusion"))
    d = render_crop_data_v2(DataConfigV2(), cache)
    print(len(d), "crops")
