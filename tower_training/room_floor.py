"""The v2 tower's score floor for apartments, derived on calibration apartments.

The shipped floor (``metrics.score_floor``, :func:`tower_training.score_floor.calibrate_score_floor_v2`)
is chosen on orbit scans of table arrangements: objects 0.5-1.4 m away, filling much of the
frame. An object-search robot sees an apartment otherwise (from about 1.2 m up, one to a few
metres away, small in a 160 x 120 frame), and its crops score lower against their names, so a
table floor drops present goals there. This module derives floors for apartments by the same
rule on what such a robot sees: ``metrics.score_floor_household`` (160 x 120 views, the default
proposals: ``spatial-v2``'s apartment scans) and ``metrics.score_floor_search`` (``--setting
search``: 320 x 240 views with the small-object proposals of
:data:`~conceptfusion.perception.featurizer.SEARCH_PROPOSER`, as the search agents see):

* **scenes**: v2 apartments (:func:`~sim_envs.scenes.gen_household_v2.generate_household_v2`) of
  ``calibration`` seeds from :data:`RoomFloorConfig.seed_offset` on (the table calibration takes
  the first calibration seeds; no evaluation scene, no tower training scene): the first half
  chooses the floor, the second half only measures it;
* **views**: :func:`~tower_training.room_views.room_poses` views (a free floor cell of an
  object's room, eye 0.9-1.45 m, the search camera's 70 degree field of view) at the setting's
  image size, fused into one map per apartment as an agent's mapper fuses them;
* **names and rule**: as on tables: present names are the categories of objects the views saw
  (at least ``min_pixels`` pixels), absent names every other library category except those the
  apartment has as furniture (its chairs and bookshelves are there, though not as objects); the
  floor maximises balanced accuracy (:func:`~tower_training.score_floor.choose_floor`).

The search agents (``map-navigator``, ``frame-searcher``) read the search floor and the map
suites on apartments the household one, through
:func:`conceptfusion.perception.featurizer.score_floor_for`; a tower without them falls back to
the household floor, then to its table floor.

    python -m tower_training.room_floor --dry-run            # derive and print
    python -m tower_training.room_floor                      # derive and write into the shipped v2 tower
    python -m tower_training.room_floor --tower-dir DIR      # another exported tower
    python -m tower_training.room_floor --setting search     # the search agents' floor (score_floor_search)
    python -m tower_training.room_floor --size 320x240       # views at another image size
    python -m tower_training.room_floor --proposer rgbd:max_masks=32   # another proposer
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from conceptfusion.perception.featurizer import score_floor_key as floor_key
from tower_training.evaluate import parse_image_size
from tower_training.score_floor import frames_query_scores, library_floor, write_score_floor
from tower_training.room_views import RoomViewConfig

__all__ = ["RoomFloorConfig", "setting_config", "floor_key", "room_floor_seeds", "apartment_query_scores", "calibrate_room_floor", "write_room_floor", "main"]

FLOOR_KEY = floor_key("household")
"""Where the household floor goes in ``tower.json``'s ``metrics`` (its rates: ``FLOOR_KEY + "_calibration"``;
:func:`floor_key` names any setting's, the key the featurizer reads)."""


@dataclass(frozen=True)
class RoomFloorConfig:
    """Which calibration apartments, and how they are seen."""

    scenes: int = 12
    """Apartments: the first half chooses the floor, the second half measures it."""
    seed_offset: int = 100
    """Index of the first apartment seed among the ``calibration`` seeds (the table calibration
    uses the first 12)."""
    views: int = 40
    """Views per apartment (each looks at a random object of the apartment)."""
    min_pixels: int = 60
    """Pixels of an object over the views for its name to count as present."""
    view: RoomViewConfig = field(default_factory=lambda: RoomViewConfig(width=160, height=120))
    """Camera placement and image size (160 x 120: ``spatial-v2``'s apartment scans)."""
    rng_seed: int = 0
    """Seed of the views' randomness."""
    setting: str = "household"
    """The floor setting derived (:data:`~conceptfusion.perception.featurizer.FLOOR_SETTINGS`):
    it names the key written, ``metrics.score_floor_<setting>``."""
    proposer: str = "rgbd"
    """Mask proposer spec of the perception the floor is for."""

    def __post_init__(self) -> None:
        from conceptfusion.perception.featurizer import FLOOR_SETTINGS

        if self.setting not in FLOOR_SETTINGS or self.setting == "tabletop":
            raise ValueError(f"setting: expected an apartment setting ({', '.join(s for s in FLOOR_SETTINGS if s != 'tabletop')}), "
                             f"got {self.setting!r}")
        for name in ("scenes", "views", "min_pixels"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < (2 if name == "scenes" else 1):
                raise ValueError(f"{name}: expected an integer >= {2 if name == 'scenes' else 1}, got {value!r}")
        if isinstance(self.seed_offset, bool) or not isinstance(self.seed_offset, int) or self.seed_offset < 0:
            raise ValueError(f"seed_offset: expected an integer >= 0, got {self.seed_offset!r}")


def setting_config(setting: str) -> RoomFloorConfig:
    """How the floor of an apartment setting is derived: ``"household"`` at 160 x 120 with the
    default proposer; ``"search"`` as the search agents see (the ``search-v2`` camera's 320 x 240
    and :data:`~conceptfusion.perception.featurizer.SEARCH_PROPOSER`). Both on the same apartments.

    Raises:
        ValueError: not an apartment setting.
    """
    if setting == "search":
        from conceptfusion.perception.featurizer import SEARCH_PROPOSER

        return RoomFloorConfig(setting="search", proposer=SEARCH_PROPOSER, view=RoomViewConfig(width=320, height=240))
    return RoomFloorConfig(setting=setting)


def room_floor_seeds(config: RoomFloorConfig, split=None) -> list[int]:
    """The apartment seeds of a calibration: ``calibration`` seeds ``seed_offset ..`` ``seed_offset + scenes - 1``."""
    from sim_envs.scenes.splits import splits

    from sim_envs.scenes.sealed import refuse_sealed

    sp = splits() if split is None else split
    seeds = sp.seeds_of("calibration", config.seed_offset + config.scenes)[config.seed_offset:]
    refuse_sealed(seeds, "python -m tower_training.room_floor")
    return seeds


def apartment_query_scores(seed: int, featurizer, vocabulary, config: RoomFloorConfig, rng: np.random.Generator) -> dict:
    """Render ``config.views`` robot-height views of apartment ``seed``, fuse them and score every
    name of ``vocabulary`` but the apartment's furniture categories
    (:func:`~tower_training.score_floor.frames_query_scores`)."""
    from sim_envs.scenes.gen_household_v2 import generate_household_v2
    from tower_training.library_views import labelled_views
    from tower_training.room_views import room_poses

    scene = generate_household_v2(int(seed))
    obs, seen = [], np.zeros(len(scene.objects), np.int64)
    for v in labelled_views([int(seed)], lambda s: scene, room_poses, config.views, rng, config.view):
        obs.append(v.frame.observation())
        ids, counts = np.unique(v.frame.segmentation[v.frame.segmentation >= 0], return_counts=True)
        seen[ids] += counts
    furniture = {f.category for f in scene.furniture}  # a "chair" the apartment has as furniture is not absent
    return frames_query_scores(scene, obs, seen, featurizer, [n for n in vocabulary if n not in furniture], config.min_pixels,
                               name_of=lambda o: o.category)


def calibrate_room_floor(config: RoomFloorConfig = RoomFloorConfig(), *, encoder=None, log=print) -> dict:
    """Derive an apartment floor (see the module docstring) for ``encoder`` (default: the shipped
    v2 tower) with ``config.proposer``'s masks; returns ``{"score_floor", "calibration": {...}, "validation": {...},
    "seeds", "config"}``, the splits' rates as :func:`~tower_training.score_floor.calibrate_score_floor_v2`
    reports them (``absent_rejected_same_parent``: absent names sharing a parent group with a
    present object)."""
    from conceptfusion.perception.featurizer import PerceivedFeaturizer, PerceptionSpec, make_featurizer
    from conceptfusion.perception.masks.registry import make_proposer
    from sim_envs.assets.library import catalogue

    featurizer = (make_featurizer(PerceptionSpec.parse("embedded-v2", proposer=config.proposer)) if encoder is None
                  else PerceivedFeaturizer(encoder, make_proposer(config.proposer)))
    cat = catalogue()
    vocab = sorted(cat.categories)
    seeds = room_floor_seeds(config)
    half = len(seeds) // 2
    rng = np.random.default_rng(config.rng_seed)
    per_split: dict[str, list[dict]] = {"calibration": [], "validation": []}
    for k, seed in enumerate(seeds):
        t0 = time.perf_counter()
        r = apartment_query_scores(seed, featurizer, vocab, config, rng)
        part = "calibration" if k < half else "validation"
        per_split[part].append(r)
        log(f"{part} {r['scene']}: {len(r['present'])} present, {len(r['absent'])} absent names, "
            f"{len(r['unseen'])} barely seen ({time.perf_counter() - t0:.1f} s)")
    floor, summaries = library_floor(per_split)
    cfg = asdict(config)
    cfg["view"] = {k: list(v) if isinstance(v, tuple) else v for k, v in cfg["view"].items()}
    return {"score_floor": floor, "world": "v2", "setting": config.setting, "seeds": seeds, "config": cfg, **summaries}


def write_room_floor(result: dict, tower_dir: str | Path | None = None) -> Path:
    """Write a calibration into ``tower.json`` atomically: ``metrics.score_floor_<setting>`` and
    ``metrics.score_floor_<setting>_calibration``; other fields are kept."""
    from conceptfusion.perception.image_tower import SHIPPED_TOWER_V2_DIR

    return write_score_floor(result, SHIPPED_TOWER_V2_DIR if tower_dir is None else tower_dir, key=floor_key(result["setting"]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tower_training.room_floor", description=__doc__.split("\n\n")[0])
    p.add_argument("--tower-dir", default=None, help="tower folder (default: the shipped v2 tower)")
    p.add_argument("--dry-run", action="store_true", help="print the calibration, write nothing")
    p.add_argument("--scenes", type=int, default=RoomFloorConfig.scenes, help="calibration apartments (half choose, half measure)")
    p.add_argument("--views", type=int, default=RoomFloorConfig.views, help="views per apartment")
    p.add_argument("--setting", choices=("household", "search"), default="household",
                   help="household: 160x120 views, default proposals; search: the search agents' 320x240 views and proposals")
    p.add_argument("--size", default=None, help="view image size WIDTHxHEIGHT (default: the setting's)")
    p.add_argument("--proposer", default=None, help="mask proposer spec (default: the setting's)")
    args = p.parse_args(argv)
    base = setting_config(args.setting)
    width, height = parse_image_size(p, args.size) if args.size else (base.view.width, base.view.height)
    proposer = base.proposer if args.proposer is None else args.proposer
    try:
        from conceptfusion.perception.featurizer import PerceptionSpec

        PerceptionSpec.parse("embedded-v2", proposer=proposer)  # names and settings checked, nothing built
    except ValueError as exc:
        p.error(f"--proposer: {exc}")
    encoder = None
    if args.tower_dir is not None:
        from conceptfusion.perception.registry import make_encoder

        encoder = make_encoder(f"embedded:{args.tower_dir}")
    t0 = time.perf_counter()
    view = dataclasses.replace(base.view, width=width, height=height)
    result = calibrate_room_floor(dataclasses.replace(base, scenes=args.scenes, views=args.views, view=view, proposer=proposer),
                                  encoder=encoder)
    for part in ("calibration", "validation"):
        r = result[part]
        print(f"{part}: floor {result['score_floor']:.3f}: present found {r['present_found']:.3f} (n={r['n_present']}), "
              f"absent rejected {r['absent_rejected']:.3f} (n={r['n_absent']}; same parent rejected "
              f"{r['absent_rejected_same_parent']:.3f}, n={r['n_absent_same_parent']}), balanced accuracy {r['balanced_accuracy']:.3f}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    if not args.dry_run:
        print(f"wrote {write_room_floor(result, args.tower_dir)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
