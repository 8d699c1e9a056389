"""The embedded tower's **score floor**: "is this object in the map at all?"

The floor is the median cosine score the best region of a map query must reach for an agent's
concept mapper (``agents.concept_map.ConceptMapper``) to report the object found. It is chosen,
never set by hand, on scenes no evaluation suite uses: orbit scans of reserved shipped tables
(v1, :func:`calibrate_score_floor`) or library arrangements of ``calibration`` seeds (v2,
:func:`calibrate_score_floor_v2`; the apartment floor is :mod:`tower_training.room_floor`), a map
per scene, the floor that maximises balanced accuracy between present and absent names
(:func:`choose_floor`), measured again on other scenes. ``python -m tower_training.evaluate
--calibrate-floor [--world v2]`` runs it and writes the floor into the tower's ``tower.json``
(:func:`write_score_floor`).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from sim_envs.scenes.splits import V1_FLOOR_CALIBRATION_SCENES, V1_FLOOR_VALIDATION_SCENES

__all__ = [
    "FloorConfig", "map_query_scores", "choose_floor", "floor_rates", "calibrate_score_floor", "write_score_floor",
    "orbit_scan", "scene_query_scores", "FloorConfigV2", "calibrate_score_floor_v2", "frames_query_scores",
    "pooled_scores", "floor_summary", "library_floor",
]


@dataclass(frozen=True)
class FloorConfig:
    """What the score-floor calibration scans and queries (cheap by default: ~1 min on 2 cores)."""

    calibration_scenes: tuple[str, ...] = V1_FLOOR_CALIBRATION_SCENES
    """Shipped tabletop scenes the floor is chosen on (every 8th shipped scene; reserved in the split
    file, so no evaluation suite uses them)."""
    validation_scenes: tuple[str, ...] = V1_FLOOR_VALIDATION_SCENES
    """Other shipped tabletop scenes (every 8th from the 5th), on which the chosen floor is only
    measured (reserved in the split file too)."""
    frames: int = 12
    """Frames of the orbit scan (as the ``query`` map suite)."""
    width: int = 160
    height: int = 120
    min_pixels: int = 60
    """An object counts as present when the scan saw at least this many of its pixels in all."""


def _shipped_tabletop_vocabulary() -> list[str]:
    from sim_envs.scenes.episodes import SCENES_ROOT
    from sim_envs.scenes.format import load_scene

    return sorted({o.name for p in (SCENES_ROOT / "tabletop").glob("tabletop-*.json") for o in load_scene(p).objects})


def orbit_scan(scene, frames: int, width: int, height: int):
    """The orbit scan of a scene (as :func:`harness.maps.scan.scan_scene`): observations and
    the number of pixels seen of each object."""
    from sim_envs.mujoco.scan import scan_views
    from sim_envs.mujoco.scene import build_mujoco

    obs, seen = [], np.zeros(len(scene.objects), np.int64)
    for f in scan_views(build_mujoco(scene), frames, width, height):
        obs.append(f.observation())
        ids, counts = np.unique(f.segmentation[f.segmentation >= 0], return_counts=True)
        seen[ids] += counts
    return obs, seen


_MAP_MAX_DEPTH = 6.0
"""Depth (m) a map fuses, as the agents' ``MapperConfig.max_depth``."""


def _best_region_score(res) -> float:
    """The statistic :meth:`ConceptMapper.locate` compares with its floor: the largest median
    cosine score of a region; ``-inf`` when nothing passed the relevancy test (never found)."""
    if not res.found:
        return -math.inf
    return max(float(np.median(r.scores_n)) for r in res.regions)


def map_query_scores(
    scene_id: str, featurizer, vocabulary: Sequence[str], config: FloorConfig = FloorConfig()
) -> dict:
    """Scan one shipped tabletop scene, fuse a map, and score every name of ``vocabulary``.

    The map is built as an agent's mapper builds it (``agents.builtin.make_mapper``: the
    featurizer's features, depth up to 6 m, :func:`~conceptfusion.map.query.locate` with its
    default thresholds), but without a floor, so the returned score is the one the floor is
    compared with.

    Args:
        featurizer: the perception (:func:`conceptfusion.perception.featurizer.make_featurizer`
            or a :class:`~conceptfusion.perception.featurizer.PerceivedFeaturizer`).

    Returns:
        ``{"scene", "present": {name: score}, "absent": {name: score}, "unseen": [names]}``:
        names of objects the scan saw (``present``), vocabulary names of no object in the
        scene (``absent``), and names of objects in the scene that the scan saw too little of
        (``unseen``, not scored). A score is ``-inf`` when the query is not found even without
        a floor.
    """
    from sim_envs.scenes.episodes import SCENES_ROOT
    from sim_envs.scenes.format import load_scene

    scene = load_scene(SCENES_ROOT / "tabletop" / f"{scene_id}.json")
    return scene_query_scores(scene, featurizer, vocabulary, config)


def scene_query_scores(scene, featurizer, vocabulary: Sequence[str], config: FloorConfig = FloorConfig(),
                       *, name_of: Callable = lambda o: o.name) -> dict:
    """:func:`map_query_scores` for a :class:`~sim_envs.scenes.format.Scene` object; ``name_of``
    gives the query name of a scene object (default its ``name``; v2 uses its category)."""
    obs, seen = orbit_scan(scene, config.frames, config.width, config.height)
    return frames_query_scores(scene, obs, seen, featurizer, vocabulary, config.min_pixels, name_of=name_of)


def frames_query_scores(scene, observations: Sequence[dict], seen_n: np.ndarray, featurizer, vocabulary: Sequence[str],
                        min_pixels: int, *, name_of: Callable = lambda o: o.name) -> dict:
    """Fuse ``observations`` of ``scene`` into one map and score every name of ``vocabulary``
    (the part of :func:`map_query_scores` after the scan; any views: orbits, apartment views).

    ``seen_n`` (n objects,): pixels of each scene object over the views; a name is ``present``
    when its objects were seen at least ``min_pixels`` times, ``unseen`` when seen less.
    """
    from conceptfusion.frames import RGBDFrame
    from conceptfusion.map.fusion import PointFusionMap
    from conceptfusion.map.query import NEGATIVE_PHRASES, locate

    featurizer.reset(None)
    fmap = PointFusionMap(featurizer.dim, max_depth=_MAP_MAX_DEPTH)
    for o in observations:
        frame = RGBDFrame.from_observation(o)
        fmap.integrate(frame.rgb, frame.depth, frame.K, frame.cam_to_world, featurizer.features(frame))
    negatives = np.asarray(featurizer.encode_text(list(NEGATIVE_PHRASES)), np.float32)

    def score(name: str) -> float:
        return _best_region_score(locate(fmap, np.asarray(featurizer.encode_text([name])[0], np.float32), negatives))

    pixels: dict[str, int] = {}
    for obj, n in zip(scene.objects, seen_n):
        pixels[name_of(obj)] = pixels.get(name_of(obj), 0) + int(n)
    present = sorted(n for n, px in pixels.items() if px >= min_pixels)
    unseen = sorted(n for n, px in pixels.items() if px < min_pixels)
    absent = sorted(set(vocabulary) - set(pixels))
    return {
        "scene": scene.id,
        "present": {n: score(n) for n in present},
        "absent": {n: score(n) for n in absent},
        "unseen": unseen,
    }


def floor_rates(present: Sequence[float], absent: Sequence[float], floor: float) -> tuple[float, float]:
    """(present found rate, absent rejected rate) of a floor: found when score >= floor."""
    p, a = np.asarray(present, np.float64), np.asarray(absent, np.float64)
    found = float(np.mean(p >= floor)) if p.size else float("nan")
    rejected = float(np.mean(a < floor)) if a.size else float("nan")
    return found, rejected


def choose_floor(present: Sequence[float], absent: Sequence[float]) -> float:
    """The floor in (0, 1) that maximises balanced accuracy (mean of the present-found and
    absent-rejected rates); among equally good floors, the middle of the widest gap between
    consecutive observed scores. A score of ``-inf`` (not found even without a floor) counts as
    not found at every floor.
    """
    p, a = np.asarray(present, np.float64), np.asarray(absent, np.float64)
    if not p.size or not a.size:
        raise ValueError(f"choose_floor: expected present and absent scores, got {p.size} and {a.size}")
    vals = np.unique(np.clip(np.concatenate([p, a])[np.isfinite(np.concatenate([p, a]))], 0.0, 1.0))
    edges = np.concatenate([[0.0], vals, [1.0]])
    best, best_key = 0.5, (-1.0, -1.0)
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi <= lo:
            continue
        mid = 0.5 * (lo + hi)
        ba = float(np.mean(floor_rates(p, a, mid)))
        key = (round(ba, 12), hi - lo)
        if key > best_key:
            best, best_key = mid, key
    return float(best)


def calibrate_score_floor(config: FloorConfig = FloorConfig(), *, encoder=None, log=print) -> dict:
    """Measure map-query scores on shipped tabletop scenes and choose the score floor.

    Present names: objects of the scene the scan saw. Absent names: every other name of the
    shipped tabletop vocabulary (objects of other scenes), so same-colour and same-kind near
    misses are included. The floor maximises balanced accuracy on ``calibration_scenes``
    (:func:`choose_floor`); its rates are also measured on ``validation_scenes``.

    Args:
        encoder: the encoder to calibrate (default: the shipped embedded tower).

    Returns:
        ``{"score_floor", "calibration": {...}, "validation": {...}, "config": {...}}``, each
        split with ``present_found``, ``absent_rejected``, ``balanced_accuracy``,
        ``n_present``, ``n_absent`` and its scenes.
    """
    from dataclasses import asdict

    from conceptfusion.perception.featurizer import PerceivedFeaturizer, make_featurizer
    from conceptfusion.perception.masks.registry import make_proposer

    featurizer = make_featurizer("embedded") if encoder is None else PerceivedFeaturizer(encoder, make_proposer("rgbd"))
    vocab = _shipped_tabletop_vocabulary()
    per_split: dict[str, list[dict]] = {}
    for split, scenes in (("calibration", config.calibration_scenes), ("validation", config.validation_scenes)):
        per_split[split] = []
        for sid in scenes:
            t0 = time.perf_counter()
            r = map_query_scores(sid, featurizer, vocab, config)
            per_split[split].append(r)
            log(f"{split} {sid}: {len(r['present'])} present, {len(r['absent'])} absent names "
                f"({time.perf_counter() - t0:.1f} s)")

    floor = round(choose_floor(*pooled_scores(per_split["calibration"])), 3)
    out: dict = {"score_floor": floor, "config": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(config).items()}}
    for split, rs in per_split.items():
        # the hard absent names: same colour word as an object the scan saw ("blue mug" beside a blue can)
        hard = [s for r in rs for n, s in r["absent"].items()
                if n.split()[0] in {q.split()[0] for q in r["present"]}]
        out[split] = floor_summary(rs, floor, hard, "same_colour")
    return out


def pooled_scores(rs: list[dict]) -> tuple[list[float], list[float]]:
    """Best-region scores of present and of absent names, pooled over scenes."""
    return ([s for r in rs for s in r["present"].values()], [s for r in rs for s in r["absent"].values()])


def floor_summary(rs: list[dict], floor: float, hard: list[float], hard_kind: str, *, found_absent: int = 0) -> dict:
    """How ``floor`` decides the present and absent names of scenes ``rs``: found and rejected
    rates, the rejected rate among ``hard`` absent names (``hard_kind``: what makes them hard),
    balanced accuracy, the names it misses, and (with ``found_absent``) the first absent names it
    lets through."""
    p, a = pooled_scores(rs)
    found, rejected = floor_rates(p, a, floor)
    fp = [f"{r['scene']}: {n} ({s:.2f})" for r in rs for n, s in r["absent"].items() if s >= floor]
    fn = [f"{r['scene']}: {n} ({s:.2f})" if math.isfinite(s) else f"{r['scene']}: {n} (not found)"
          for r in rs for n, s in r["present"].items() if s < floor]
    out = {
        "present_found": round(found, 4), "absent_rejected": round(rejected, 4),
        f"absent_rejected_{hard_kind}": round(floor_rates([], hard, floor)[1], 4), f"n_absent_{hard_kind}": len(hard),
        "balanced_accuracy": round(0.5 * (found + rejected), 4),
        "absent_found_without_floor": round(float(np.mean(np.isfinite(a))), 4),
        "n_present": len(p), "n_absent": len(a), "scenes": [r["scene"] for r in rs],
        "missed_present": fn, "found_absent_count": len(fp),
    }
    if found_absent:
        out["found_absent"] = fp[:found_absent]
    return out


@dataclass(frozen=True)
class FloorConfigV2:
    """The v2 score-floor calibration: library arrangements of the ``calibration`` seed role."""

    scenes: int = 12
    """Arrangements :func:`tower_training.library_views.arrange_table` of the first ``scenes``
    calibration seeds (TRAIN and VAL instances): the first half chooses the floor, the second
    half only measures it."""
    scan: FloorConfig = FloorConfig(calibration_scenes=(), validation_scenes=())
    """Scan settings (frames, size, minimum pixels) as v1."""


def calibrate_score_floor_v2(config: FloorConfigV2 = FloorConfigV2(), *, encoder=None, log=print) -> dict:
    """:func:`calibrate_score_floor` on the v2 world: the same method (orbit scans, a map per scene,
    the floor that maximises balanced accuracy), on library arrangements of ``calibration`` seeds
    only. Present names: categories of objects the scan saw; absent: every other library category
    name. ``absent_rejected_same_parent``: absent names sharing a nearest parent group with a
    present object ("cup" beside a mug), the hard near misses.
    """
    from conceptfusion.perception.featurizer import PerceivedFeaturizer, make_featurizer
    from conceptfusion.perception.masks.registry import make_proposer
    from sim_envs.assets.library import catalogue
    from sim_envs.scenes.splits import splits
    from sim_envs.scenes.sealed import refuse_sealed
    from tower_training.library_views import arrange_table, pool_for_seed_role

    featurizer = make_featurizer("embedded") if encoder is None else PerceivedFeaturizer(encoder, make_proposer("rgbd"))
    split, cat = splits(), catalogue()
    vocab = sorted(cat.categories)
    pool = pool_for_seed_role(split, "calibration")
    seeds = split.seeds_of("calibration", config.scenes)
    refuse_sealed(seeds, "python -m tower_training.score_floor")
    half = len(seeds) // 2
    per_split: dict[str, list[dict]] = {"calibration": [], "validation": []}
    for k, seed in enumerate(seeds):
        t0 = time.perf_counter()
        scene = arrange_table(seed, pool)
        r = scene_query_scores(scene, featurizer, vocab, config.scan, name_of=lambda o: o.category)
        part = "calibration" if k < half else "validation"
        per_split[part].append(r)
        log(f"{part} {scene.id}: {len(r['present'])} present, {len(r['absent'])} absent names "
            f"({time.perf_counter() - t0:.1f} s)")

    floor, summaries = library_floor(per_split)
    return {"score_floor": floor, "world": "v2", "seeds": seeds,
            "config": {"scenes": config.scenes, "frames": config.scan.frames, "width": config.scan.width,
                       "height": config.scan.height, "min_pixels": config.scan.min_pixels}, **summaries}


def library_floor(per_split: dict[str, list[dict]]) -> tuple[float, dict[str, dict]]:
    """The floor chosen on ``per_split["calibration"]`` (library category names; rounded to 3
    decimals) and :func:`floor_summary` of every split, the hard absent names being those that
    share a nearest parent group with a present object ("cup" beside a mug)."""
    from sim_envs.assets.library import catalogue

    cats = catalogue().categories
    floor = round(choose_floor(*pooled_scores(per_split["calibration"])), 3)
    parent = {c: cats[c].parents[0] if cats[c].parents else "" for c in cats}
    summaries = {}
    for part, rs in per_split.items():
        hard = [s for r in rs for n, s in r["absent"].items() if parent[n] in {parent[q] for q in r["present"]}]
        summaries[part] = floor_summary(rs, floor, hard, "same_parent", found_absent=40)
    return floor, summaries


def write_score_floor(result: dict, tower_dir: str | Path | None = None, *, key: str = "score_floor") -> Path:
    """Write a calibration (:func:`calibrate_score_floor`) into ``tower.json`` atomically:
    ``metrics.<key>`` (what :func:`agents.builtin.make_mapper` reads; ``score_floor`` for
    tables) and ``metrics.<key>_calibration`` (the measured rates); other fields are kept."""
    from conceptfusion.perception.image_tower import SHIPPED_TOWER_DIR
    from conceptfusion.io_utils import atomic_write_text

    path = Path(SHIPPED_TOWER_DIR if tower_dir is None else tower_dir) / "tower.json"
    info = json.loads(path.read_text())
    metrics = info.setdefault("metrics", {})
    metrics[key] = float(result["score_floor"])
    metrics[key + "_calibration"] = {k: v for k, v in result.items() if k != "score_floor"}
    atomic_write_text(path, json.dumps(info, indent=2, sort_keys=True))
    return path
