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
from tower_training.data import (
    BACKGROUND_CLASS, ROOM_BACKGROUND_CLASS, ROOM_SCENE_CLASS, SCENE_CLASS, CropConfig, CropData, ObjectClass,
)

__all__ = ["DataConfigV2", "RoomDataConfig", "ROOM_TEST", "SETS", "SPECIAL_CLASSES", "library_classes", "train_caption_bank",
           "render_crop_data_v2", "render_room_crop_data", "split_summary"]

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
        from sim_envs.scenes.sealed import refuse_sealed

        n = {"train": self.train_scenes, "val": self.val_scenes, "test": self.test_scenes}[which]
        seeds = split.seeds_of(SETS[which], n)
        refuse_sealed(seeds, "tower_training")
        return seeds


@dataclass(frozen=True)
class RoomDataConfig:
    """Views of household v2 apartments from a robot base's height
    (:mod:`tower_training.room_views`). Training apartments have ``tower_train`` seeds, so TRAIN
    instances only; the test apartments (:data:`ROOM_TEST`) ``evaluation`` seeds."""

    scenes: int = 120
    """Apartments: seeds ``seed0 ..``."""
    seed0: int = 140_000
    """First apartment seed: inside ``tower_train`` and past the table arrangements' seeds."""
    role: str = "tower_train"
    """The seed role every apartment seed must have (the split file's ranges)."""
    views_per_scene: int = 10
    """Random views per apartment."""
    width: int = 320
    height: int = 240
    seed: int = 0
    """Seeds the cameras, lights and crop jitter (the apartments follow from their seeds)."""
    crops: CropConfig = CropConfig()
    """How crops are cut."""

    def scene_seeds(self, split: Splits) -> list[int]:
        """The apartment seeds; each must lie in the range of ``role``."""
        from sim_envs.scenes.splits import SplitError

        from sim_envs.scenes.sealed import refuse_sealed

        seeds = list(range(self.seed0, self.seed0 + self.scenes))
        refuse_sealed(seeds, "tower_training")
        bad = [s for s in seeds if split.seed_role(s) != self.role]
        if bad:
            raise SplitError(f"RoomDataConfig: seeds {bad[0]}..{bad[-1]} lie outside the {self.role} range "
                             f"{split.seeds.get(self.role)}")
        return seeds


ROOM_TEST = RoomDataConfig(scenes=20, seed0=305_000, role="evaluation", seed=1)
"""The tower's held-out apartment views: 20 apartments of ``evaluation`` seeds that no shipped
scene uses (``household-v2`` scenes are 300000-300019), 10 views each, with TRAIN, VAL and TEST
instances. Read once per tower, after model selection (``room_test/...`` metrics)."""


SPECIAL_CLASSES = (BACKGROUND_CLASS, SCENE_CLASS, ROOM_BACKGROUND_CLASS, ROOM_SCENE_CLASS)
"""The classes that are no object: background masks and whole views, of tables and of rooms."""


def library_classes() -> list[ObjectClass]:
    """One class per library instance (name: the instance id), catalogue order; phrases are its
    captions, category and colour filled in."""
    cat = catalogue()
    return [ObjectClass(i.id, tuple(c.text for c in instance_captions(i, cat)), i.category, i.color)
            for i in cat.instances.values()]


def train_caption_bank(split: Splits | None = None) -> CaptionBank:
    """The captions of TRAIN instances, plus the background and scene classes' phrases.

    Classes: TRAIN instance ids (sorted), then the :data:`SPECIAL_CLASSES` (table background,
    table scene, room background, room scene). No text of a VAL or TEST category name enters the
    bank unless a train category shares it.
    """
    split = splits() if split is None else split
    cat = catalogue()
    pairs = [(iid, instance_captions(cat.instances[iid], cat)) for iid in split.instances_of("train")]
    for special in SPECIAL_CLASSES:
        kind = "background" if special in (BACKGROUND_CLASS, ROOM_BACKGROUND_CLASS) else "scene"
        pairs.append((special.name, [Caption(p, kind) for p in special.phrases]))
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


def _cached_crops(cache_dir: Path | None, stem: str, key: str, config, build) -> CropData:
    """The crops of ``config``: loaded from ``cache_dir`` when an earlier build saved them there,
    else ``build()``, saved (when ``cache_dir`` is given). The file is
    ``<stem>_<hash>.npz``, the hash over ``{key: asdict(config)}`` and the catalogue's hash."""
    if cache_dir is None:
        return build()
    from sim_envs.assets.library import catalogue_hash

    key_src = json.dumps({key: asdict(config), "catalogue": catalogue_hash()}, sort_keys=True)
    path = Path(cache_dir) / f"{stem}_{hashlib.sha256(key_src.encode()).hexdigest()[:16]}.npz"
    if path.is_file():
        logger.info("crop data from cache %s", path)
        return CropData.load(path)
    data = build()
    data.save(path)
    logger.info("crop data cached at %s", path)
    return data


def render_crop_data_v2(config: DataConfigV2, cache_dir: Path | None = None, *, proposer=None) -> CropData:
    """Render (or load from the cache) the crops of the train, val and test arrangements.

    Labels index ``library_classes() + [BACKGROUND_CLASS, SCENE_CLASS]``; ``seeds`` tell the sets
    apart (:meth:`DataConfigV2.seeds`).

    Args:
        proposer: mask proposer for proposer/background crops (default: ``make_proposer("rgbd")``).
    """
    def build() -> CropData:
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
        return build_crop_data(views, classes, rng, proposer=make_proposer("rgbd") if proposer is None else proposer,
                               config=config.crops)

    return _cached_crops(cache_dir, "tower_crops_v2", "config", config, build)


def render_room_crop_data(config: RoomDataConfig, cache_dir: Path | None = None, *, proposer=None) -> CropData:
    """Render (or load from the cache) the crops of the training apartments' views.

    Labels index ``library_classes() + list(SPECIAL_CLASSES)``; background masks are labelled
    :data:`~tower_training.data.ROOM_BACKGROUND_CLASS`, whole views
    :data:`~tower_training.data.ROOM_SCENE_CLASS`.
    """
    def build() -> CropData:
        from conceptfusion.perception.masks.registry import make_proposer
        from tower_training.data import build_crop_data
        from tower_training.room_views import RoomViewConfig, random_room_views

        rng = np.random.default_rng(config.seed)
        views = random_room_views(config.scene_seeds(splits()), config.views_per_scene, rng,
                                  RoomViewConfig(width=config.width, height=config.height))
        return build_crop_data(views, library_classes() + list(SPECIAL_CLASSES), rng,
                               proposer=make_proposer("rgbd") if proposer is None else proposer, config=config.crops,
                               background_class=ROOM_BACKGROUND_CLASS, scene_class=ROOM_SCENE_CLASS)

    return _cached_crops(cache_dir, "tower_crops_rooms", "rooms", config, build)


if __name__ == "__main__":  # render the default data into the default cache
    import os
    import sys

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    cache = Path(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.expanduser("~/.cache"), "conceptfusion"))
    d = render_crop_data_v2(DataConfigV2(), cache)
    print(len(d), "table crops")
    r = render_room_crop_data(RoomDataConfig(), cache)
    print(len(r), "room crops")
