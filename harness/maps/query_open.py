"""The ``query-open`` map suite: open-vocabulary text queries over fused maps of the v2 tabletops
(the analogue of the paper's UnCoCo evaluation).

**Scenes**: the shipped v2 tabletops (``scenes/tabletop-v2/``, evaluation seeds only; 4-12
objects each from the object library), the first :data:`DEFAULT_SCENES` by default.

**Task**: scan a scene (orbit), fuse a map with the run's encoder and the ``rgbd`` proposer
(``oracle``: privileged ground-truth features labelled with each object's name; ``oracle-open``:
privileged ground-truth features and ground-truth grounding of the phrases), then query it in
words of seven kinds (:data:`QUERY_KINDS`), phrased as an instruction would name the object:

- ``name``: the category name, ``"the mug"``;
- ``synonym``: a synonym of it, ``"the coffee mug"``;
- ``parent``: a group above it in the library's taxonomy, ``"the drinkware"``;
- ``colour``, ``material``: an attribute plus the name, ``"the red mug"``, ``"the ceramic mug"``;
- ``function``: what it is for, ``"something to drink from"``;
- ``absent``: the name of a library category that nothing on the table answers to.

Phrases come from :func:`sim_envs.scenes.descriptions.describable`; per object and kind one is
drawn (seeded by the scene and the run's seed). **Ground truth** of a phrase: every object that
answers to it (:func:`sim_envs.scenes.descriptions.referents`: "the drinkware" with a mug and a
glass on the table means both), as map points inside their boxes
(:func:`harness.maps.scan.point_labels`). A phrase is asked once per scene.

**Scoring** per query, as in the ``query`` suite: the 3D IoU of the best region of
:func:`conceptfusion.map.query.locate` (with the encoder's score floor) with the ground-truth
points, detection at IoU > 0.25 and whether anything was found; for ``absent`` queries a found
region is a false positive. Each query is labelled with the **split** of its object
(:data:`SPLIT_GROUPS`, from ``scenes/splits-v1.json``): ``seen`` (an instance the tower trained
on), ``held_out_instance`` (an unseen instance of a trained category), ``held_out_category`` (a
category held out from training entirely) or ``validation`` (instances and categories used for
model selection); a phrase that several objects answer to takes the least seen of their groups.

Metrics per record (one scene, one encoder): ``{kind}_miou``, ``{kind}_acc25``,
``{kind}_found_rate`` and ``{group}_miou``, ``{group}_acc25``, ``{group}_found_rate`` over the
present-object queries, ``absent_fp_rate``, and the query counts. Scene means are noisy with a
few queries per scene: :func:`pooled_table` pools the queries of many records (query-level
means, with counts), which is what the report and the README quote.
"""

from __future__ import annotations

import dataclasses
import time
import zlib
from collections import defaultdict
from pathlib import Path

import numpy as np

from agents.builtin import make_mapper
from harness.maps.query import iou, select_points
from harness.maps.scan import fuse_frames, point_labels, scan_scene
from sim_envs.assets.library import catalogue
from sim_envs.scenes.descriptions import describable, referents
from sim_envs.scenes.episodes import SCENES_ROOT
from sim_envs.scenes.format import Scene, load_scene
from sim_envs.scenes.splits import SPLIT_GROUPS, object_group, splits

__all__ = [
    "QUERY_KINDS", "SPLIT_GROUPS", "DEFAULT_SCENES", "SCENE_FOLDER", "SCAN_SIZE", "open_scene_ids", "load_open_scene", "object_group",
    "open_queries", "run_open_query_scene", "score_open_query_scene", "pooled_table", "format_table", "main",
]

QUERY_KINDS = ("name", "synonym", "parent", "colour", "material", "function", "absent")
"""Kinds of query, in report order."""

DEFAULT_SCENES = 24
"""v2 tabletops the suite uses without ``--limit``."""

SCENE_FOLDER = SCENES_ROOT / "tabletop-v2"
"""Where its scenes come from."""

SCAN_SIZE = (320, 240)
"""Width and height of the suite's scan frames (12 frames of an orbit), the size the v2 tower
was trained at; chosen on calibration tables (:mod:`harness.maps.query_open_develop`), see
docs/measurement-history.md. ``--agent-option width=160 --agent-option height=120`` gives
160x120 scans."""

_ABSENT_PER_SCENE = 3
_REL = 0.6
_ACC = 0.25
_GROUP_RANK = {"seen": 0, "validation": 1, "held_out_instance": 2, "held_out_category": 3}


def open_scene_ids(limit: int | None = None) -> list[str]:
    """Ids of the shipped v2 tabletops, sorted; the first ``limit`` (default :data:`DEFAULT_SCENES`)."""
    ids = sorted(p.stem for p in SCENE_FOLDER.glob("tabletop-v2-*.json"))
    n = DEFAULT_SCENES if limit is None else int(limit)
    if n < 0:
        raise ValueError(f"limit: expected a non-negative number of scenes, got {limit}")
    return ids[:n]


def load_open_scene(scene_id: str) -> Scene:
    """A shipped v2 tabletop by id (``"tabletop-v2-300005"``)."""
    path = SCENE_FOLDER / f"{scene_id}.json"
    if not str(scene_id).startswith("tabletop-v2-") or not path.is_file():
        known = open_scene_ids(None)[:3]
        raise ValueError(f"query-open: expected a v2 tabletop id such as {known[0] if known else 'tabletop-v2-300005'!r}, "
                         f"got {scene_id!r} (no file {path})")
    return load_scene(path)


def _phrases(obj, kind: str) -> tuple[str, ...]:
    d = describable(obj)
    if kind in ("colour", "material"):
        word = d.color if kind == "colour" else d.material
        if not word or word == "organic" or word in d.name.split():  # not "the glass wine glass"
            return ()
        return (f"the {word} {d.name}",)
    return d.phrases(kind)


def open_queries(scene: Scene, seed: int = 0) -> list[dict]:
    """The queries of one scene: ``{"kind", "text", "objects" (ids of the referents; empty for
    absent), "group"}``, each phrase once, in a fixed order (objects, then kinds; absent last).

    Deterministic given the scene and ``seed``.
    """
    rng = np.random.default_rng([int(seed), zlib.crc32(scene.id.encode())])
    out, asked = [], set()
    for obj in scene.objects:
        for kind in QUERY_KINDS[:-1]:
            options = _phrases(obj, kind)
            if not options:
                continue
            text = options[int(rng.integers(len(options)))]
            if text in asked:
                continue
            refs = referents(text, scene.objects) or [obj]
            asked.add(text)
            group = max((object_group(o) for o in refs), key=_GROUP_RANK.__getitem__)
            out.append({"kind": kind, "text": text, "objects": [o.id for o in refs], "group": group})
    answered = set().union(*(describable(o).answers_to() for o in scene.objects)) if scene.objects else set()
    present = {describable(o).name for o in scene.objects}
    pool = sorted(c for c in catalogue().categories if c not in present and f"the {c}" not in answered)
    for name in rng.choice(pool, size=min(_ABSENT_PER_SCENE, len(pool)), replace=False):
        role = splits().categories[str(name)]
        group = {"train": "seen", "val": "validation", "test": "held_out_category"}[role]
        out.append({"kind": "absent", "text": f"the {name}", "objects": [], "group": group})
    return out


def _means(entries: list[dict]) -> dict:
    if not entries:
        return {"miou": None, "acc25": None, "found_rate": None, "n": 0}
    ious = np.asarray([e["iou"] for e in entries], float)
    return {"miou": float(ious.mean()), "acc25": float((ious > _ACC).mean()),
            "found_rate": float(np.mean([e["found"] for e in entries])), "n": len(entries)}


def run_open_query_scene(scene_id: str, encoder: str, *, frames: int = 12, width: int = SCAN_SIZE[0], height: int = SCAN_SIZE[1],
                         seed: int = 0) -> tuple[dict, dict, dict]:
    """Run the suite on one shipped v2 tabletop with one encoder: :func:`score_open_query_scene`
    of :func:`load_open_scene`; returns ``(metrics, extras, timings)``."""
    t0 = time.perf_counter()
    scene = load_open_scene(scene_id)
    t_load = time.perf_counter() - t0
    metrics, extras, timings = score_open_query_scene(scene, encoder, frames=frames, width=width, height=height, seed=seed)
    timings["scan_s"] += t_load  # the scene file's load counts as scanning, as before
    extras["scene"] = str(Path("tabletop-v2") / f"{scene_id}.json")
    return metrics, extras, timings


def score_open_query_scene(scene: Scene, encoder: str, *, frames: int = 12, width: int = SCAN_SIZE[0], height: int = SCAN_SIZE[1],
                           seed: int = 0, floor: bool = True, all_regions: bool = False,
                           drop_support: bool = True) -> tuple[dict, dict, dict]:
    """Scan a loaded v2 tabletop, fuse a map with ``encoder`` and score its queries
    (:func:`open_queries`); returns ``(metrics, extras, timings)``.

    ``extras["queries"]``: one entry per query (kind, text, group, objects, iou, found, score).
    ``floor=False`` asks without the encoder's score floor (regions need only beat the generic
    phrases); ``all_regions`` adds ``regions`` to each found entry: ``[median score, IoU]`` of every
    region in the answer's order (``[median score]`` for absent queries), from which the floored
    answer at any floor follows (the first region whose median reaches it), for choosing a floor
    on calibration tables (:mod:`harness.maps.query_open_develop`). ``drop_support=False`` answers
    with whole regions (the mapper's ``MapperConfig.drop_support`` off).
    """
    t0 = time.perf_counter()
    scan = scan_scene(scene, frames=frames, width=width, height=height)
    t_scan = time.perf_counter() - t0
    mapper = make_mapper(encoder, "rgbd")
    if not drop_support:
        mapper.config = dataclasses.replace(mapper.config, drop_support=False)
    mapper = fuse_frames(mapper, scan)
    t_fuse = time.perf_counter() - t0 - t_scan
    pts = mapper.map.points
    gt = point_labels(pts, scan.object_boxes)
    index = {o.id: i for i, o in enumerate(scene.objects)}
    entries, absent, unseen = [], [], 0
    for q in open_queries(scene, seed):
        res = mapper.locate(q["text"], floor=floor)
        entry = {**q, "found": bool(res.found), "score": round(float(res.best.score), 4) if res.found else None}
        truth = None
        if q["kind"] != "absent":
            truth = np.isin(gt, [index[i] for i in q["objects"]])
            if not truth.any():
                unseen += 1
                continue
        if all_regions and res.found:
            entry["regions"] = [[round(float(np.median(r.scores_n)), 4)]
                                + ([] if truth is None else [round(iou(_mask(r, len(pts)), truth), 4)]) for r in res.regions]
        if truth is None:
            absent.append(entry)
            continue
        region, _ = select_points(res, len(pts), _REL)
        entry["iou"] = round(iou(region, truth), 4)
        entries.append(entry)
    metrics: dict = {}
    for kind in QUERY_KINDS[:-1]:
        m = _means([e for e in entries if e["kind"] == kind])
        metrics.update({f"{kind}_{k}": v for k, v in m.items() if k != "n"})
    for group in SPLIT_GROUPS:
        m = _means([e for e in entries if e["group"] == group])
        metrics.update({f"{group}_{k}": v for k, v in m.items() if k != "n"})
    metrics.update({
        "absent_fp_rate": float(np.mean([a["found"] for a in absent])) if absent else None,
        "n_queries": len(entries), "n_absent": len(absent), "n_unseen": unseen, "map_points": int(len(pts)),
    })
    extras = {"queries": entries + absent, "frames": frames, "image_size": [width, height],
              "privileged": bool(mapper.privileged), "scene": scene.id}
    timings = {"scan_s": t_scan, "fuse_s": t_fuse, "query_s": time.perf_counter() - t0 - t_scan - t_fuse}
    return metrics, extras, timings


def _mask(region, n: int) -> np.ndarray:
    out = np.zeros(n, bool)
    out[region.indices_n] = True
    return out


def pooled_table(records: list[dict]) -> dict[tuple[str, str, str], dict]:
    """Query-level figures pooled over ``query-open`` records (ok records only).

    Returns ``{(encoder, kind, group): {"miou", "acc25", "found_rate", "n"}}`` with ``kind`` in
    :data:`QUERY_KINDS` or ``"all"`` (present-object kinds together) and ``group`` in
    :data:`SPLIT_GROUPS` or ``"all"``; for ``absent`` the figures are ``{"fp_rate", "n"}``.
    """
    pools: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
    for rec in records:
        if rec.get("suite") != "query-open" or rec.get("status") != "ok":
            continue
        enc = str(rec.get("encoder"))
        for e in (rec.get("extras") or {}).get("queries", []):
            for kind in (e["kind"], "all") if e["kind"] != "absent" else ("absent",):
                for group in (e["group"], "all"):
                    pools[(enc, kind, group)].append(e)
    out = {}
    for key, entries in sorted(pools.items()):
        if key[1] == "absent":
            out[key] = {"fp_rate": float(np.mean([e["found"] for e in entries])), "n": len(entries)}
        else:
            out[key] = _means(entries)
    return out


def format_table(table: dict[tuple[str, str, str], dict], *, groups: tuple[str, ...] = ("seen", "held_out_instance", "held_out_category")) -> str:
    """A Markdown table of :func:`pooled_table`: one row per (encoder, kind), per split group
    ``mIoU / acc@0.25 / found (n)``; absent rows give the false-positive rate."""
    head = "| encoder | query | " + " | ".join(g.replace("_", " ") for g in groups) + " | all |"
    lines = [head, "|" + "---|" * (len(groups) + 3)]
    encoders = sorted({k[0] for k in table})
    for enc in encoders:
        for kind in (*QUERY_KINDS[:-1], "all", "absent"):
            cells = []
            for group in (*groups, "all"):
                row = table.get((enc, kind, group))
                if row is None:
                    cells.append("-")
                elif kind == "absent":
                    cells.append(f"FP {row['fp_rate']:.2f} ({row['n']})")
                else:
                    cells.append(f"{row['miou']:.2f} / {row['acc25']:.2f} / {row['found_rate']:.2f} ({row['n']})")
            lines.append(f"| {enc} | {kind} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m harness.maps.query_open RUN...``: the pooled ``query-open`` table of run folders."""
    import argparse

    from harness.runner.results import RESULTS_FILE, load_results

    parser = argparse.ArgumentParser(prog="python -m harness.maps.query_open", description=main.__doc__)
    parser.add_argument("runs", nargs="+", help="run folders (or results files) holding query-open records")
    args = parser.parse_args(argv)
    records = []
    for run in args.runs:
        p = Path(run)
        records += load_results(p / RESULTS_FILE if p.is_dir() else p)
    table = pooled_table(records)
    if not table:
        print(f"no ok query-open records in {', '.join(args.runs)}")
        return 1
    print("mIoU / accuracy at IoU 0.25 / found rate (queries); absent: false-positive rate (queries)\n")
    print(format_table(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
