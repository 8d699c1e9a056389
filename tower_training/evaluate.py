"""Retrieval metrics of the embedded image tower on labelled crops.

Every metric is top-1 crop-to-text retrieval: a crop is embedded, compared by cosine with
the embeddings of a list of query texts, and counts as right when the best text is its
own. The texts are what a user would type, not the training targets:

* ``instance``: the 70 instance names ("red mug"), every colour x category, held-out
  ones included;
* ``category``: "a mug", "a can", ... (7);
* ``colour``: "red", "green", ... (10);
* ``paraphrase``: every distinct category description ("something to drink", "a coffee
  mug", ...); right when the best one describes the crop's category (a phrase shared by
  two categories counts for both);
* ``background``: the 70 names plus the background class's first phrase; right when the
  background phrase wins.

It also calibrates the tower's **score floor** (:func:`calibrate_score_floor`): the median
cosine score the best region of a map query must reach for an agent's concept mapper
(``agents.concept_map.ConceptMapper``) to report the object found. Run
``python -m tower_training.evaluate --calibrate-floor`` to measure it on shipped tabletop
scenes and write it into the shipped ``tower.json`` (``metrics.score_floor``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from sim_envs.scenes.splits import V1_FLOOR_CALIBRATION_SCENES, V1_FLOOR_VALIDATION_SCENES
from tower_training.data import BACKGROUND_CLASS, SOURCES, CropData, ObjectClass

__all__ = [
    "top1", "evaluate_crops", "FloorConfig", "map_query_scores", "choose_floor", "floor_rates",
    "calibrate_score_floor", "write_score_floor", "orbit_scan", "main", "scene_query_scores", "FloorConfigV2",
    "calibrate_score_floor_v2", "frames_query_scores", "pooled_scores", "floor_summary", "library_floor",
]


def top1(emb_nd: np.ndarray, texts_td: np.ndarray, correct_nt: np.ndarray) -> float:
    """Fraction of rows whose best-matching text is marked correct (NaN for no rows).

    Shape:
        (n, d), (T, d), (n, T) bool -> float.
    """
    if len(emb_nd) == 0:
        return float("nan")
    best = np.argmax(emb_nd @ texts_td.T, axis=1)
    return float(np.mean(correct_nt[np.arange(len(best)), best]))


def evaluate_crops(
    embed_fn: Callable[[list], np.ndarray],
    text_encoder,
    data: CropData,
    instances: Sequence[ObjectClass],
    *,
    test_seeds: Sequence[int],
    held_out_instances: Sequence[str],
    held_out_category: str,
) -> dict:
    """Every metric of the model card, with the number of crops behind each.

    Args:
        embed_fn: crops -> (n, d) unit rows (the tower).
        text_encoder: the text tower.
        data: crops labelled with a vocabulary holding every name of ``instances`` (and
            optionally the background class).
        instances: every colour x category class.
        test_seeds: scenes never used for training (unseen viewpoints and arrangements).
        held_out_instances, held_out_category: what training never saw.

    Returns:
        ``{metric: {"top1": float, "n": int}}``.
    """
    names = [c.name for c in instances]
    cls_of = {c.name: c for c in instances}
    if held_out_category not in {c.category for c in instances}:
        raise ValueError(f"held_out_category: expected one of the instances' categories, got {held_out_category!r}")
    lab_name = np.array(data.class_names, dtype=object)[data.labels]
    is_obj = np.isin(data.sources, [SOURCES.index("gt"), SOURCES.index("proposer")]) & np.isin(lab_name, names)
    test = np.isin(data.seeds, np.asarray(test_seeds))
    held_inst = np.isin(lab_name, list(held_out_instances))
    held_cat = np.array([n in cls_of and cls_of[n].category == held_out_category for n in lab_name], bool)
    seen = is_obj & ~held_inst & ~held_cat

    sets = {
        "seen_unseen_view": seen & test,
        "seen_unseen_view_gt_crops": seen & test & (data.sources == SOURCES.index("gt")),
        "seen_unseen_view_proposer_crops": seen & test & (data.sources == SOURCES.index("proposer")),
        "held_out_instances": is_obj & held_inst,
        "held_out_category": is_obj & held_cat,
    }
    need = np.zeros(len(data), bool)
    for m in sets.values():
        need |= m
    bg = data.sources == SOURCES.index("background")
    need |= bg & test
    idx = np.flatnonzero(need)
    emb = np.zeros((len(data), 0), np.float32)
    if len(idx):
        e = np.asarray(embed_fn([data.images[i] for i in idx]), np.float32)
        emb = np.zeros((len(data), e.shape[1]), np.float32)
        emb[idx] = e

    categories = sorted({c.category for c in instances})
    colours = sorted({c.color for c in instances})
    phrases = sorted({p for c in instances for p in c.phrases[2:]})
    t_names = text_encoder.encode_text(names)
    t_cat = text_encoder.encode_text([f"a {c}" for c in categories])
    t_col = text_encoder.encode_text(colours)
    t_phr = text_encoder.encode_text(phrases)
    t_bg = text_encoder.encode_text([BACKGROUND_CLASS.phrases[0]])

    def correct(rows, fn, cands) -> np.ndarray:
        return np.array([[fn(lab_name[r], c) for c in cands] for r in rows], bool).reshape(len(rows), len(cands))

    out: dict[str, dict] = {}
    for key, mask in sets.items():
        rows = np.flatnonzero(mask)
        e = emb[rows]
        out[f"{key}/instance"] = {"top1": top1(e, t_names, correct(rows, lambda n, c: n == c, names)), "n": len(rows)}
        out[f"{key}/category"] = {
            "top1": top1(e, t_cat, correct(rows, lambda n, c: cls_of[n].category == c, categories)), "n": len(rows)}
        out[f"{key}/colour"] = {
            "top1": top1(e, t_col, correct(rows, lambda n, c: cls_of[n].color == c, colours)), "n": len(rows)}
        out[f"{key}/paraphrase"] = {
            "top1": top1(e, t_phr, correct(rows, lambda n, p: p in cls_of[n].phrases, phrases)), "n": len(rows)}
    rows = np.flatnonzero(bg & test)
    cand = np.concatenate([t_names, t_bg])
    ok = np.zeros((len(rows), len(cand)), bool)
    ok[:, -1] = True
    out["background_unseen_view/background"] = {"top1": top1(emb[rows], cand, ok), "n": len(rows)}
    return out


# --------------------------------------------------------------------------------------------
# Score floor: "is this object in the map at all?"
# --------------------------------------------------------------------------------------------


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
    from tower_training.library_views import arrange_table, pool_for_seed_role

    featurizer = make_featurizer("embedded") if encoder is None else PerceivedFeaturizer(encoder, make_proposer("rgbd"))
    split, cat = splits(), catalogue()
    vocab = sorted(cat.categories)
    pool = pool_for_seed_role(split, "calibration")
    seeds = split.seeds_of("calibration", config.scenes)
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


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m tower_training.evaluate",
                                description="Evaluate the embedded image tower in maps.")
    p.add_argument("--calibrate-floor", action="store_true",
                   help="measure map-query scores on shipped tabletop scenes, choose the score floor and write it into tower.json")
    p.add_argument("--tower-dir", default=None, help="tower folder (default: the shipped tower)")
    p.add_argument("--dry-run", action="store_true", help="print the calibration, write nothing")
    p.add_argument("--world", choices=("v1", "v2"), default="v1",
                   help="v1: shipped tabletop scenes (default); v2: library arrangements of the calibration seeds")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if not args.calibrate_floor:
        _parser().print_help()
        return 2
    encoder = None
    if args.tower_dir is not None:
        from conceptfusion.perception.registry import make_encoder

        encoder = make_encoder(f"embedded:{args.tower_dir}")
    t0 = time.perf_counter()
    result = calibrate_score_floor_v2(encoder=encoder) if args.world == "v2" else calibrate_score_floor(encoder=encoder)
    near = "parent" if args.world == "v2" else "colour"
    for split in ("calibration", "validation"):
        r = result[split]
        print(f"{split}: floor {result['score_floor']:.3f}: present found {r['present_found']:.3f} (n={r['n_present']}), "
              f"absent rejected {r['absent_rejected']:.3f} (n={r['n_absent']}; found without a floor "
              f"{r['absent_found_without_floor']:.3f}; same {near} as a present object rejected "
              f"{r[f'absent_rejected_same_{near}']:.3f}, n={r[f'n_absent_same_{near}']}), "
              f"balanced accuracy {r['balanced_accuracy']:.3f}")
        for m in r["missed_present"]:
            print(f"  missed present: {m}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    if not args.dry_run:
        print(f"wrote {write_score_floor(result, args.tower_dir)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
