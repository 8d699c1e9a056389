"""``query-open`` on calibration tables: what the score floor costs, measured where settings are chosen.

``python -m harness.maps.query_open_develop [--tables N] [--encoder SPEC] [--frames N --width W
--height H] [--whole-regions]`` asks the
``query-open`` queries (:func:`harness.maps.query_open.open_queries`: six kinds of phrase per
object, three absent categories per table) over maps of the first N v2 calibration tables
(``scenes/calibration-v2/``: calibration seeds, TRAIN instances only, no evaluation scene), with
the suite's scan and scoring (:func:`~harness.maps.query_open.score_open_query_scene`) but
without the floor, keeping every region's median score and IoU. From those it prints, with the
encoder's own floor and with none:

- per query kind: found rate, 3D mIoU and the IoU of the answers found;
- the share of absent categories reported found;
- the ROC AUC of the best region's median score, present against absent queries (how well any
  floor on that score can separate them), and the floor :func:`tower_training.score_floor.choose_floor`
  picks on these queries (balanced accuracy);
- a sweep of floors: present found rate, mIoU, absent found rate.

The floored answer at a floor is the first region (in the answer's order) whose median score
reaches it, as :meth:`agents.concept_map.ConceptMapper.locate` keeps them, so one pass gives every
floor exactly.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from harness.maps.query_open import QUERY_KINDS, SCAN_SIZE
from harness.maps.spatial_develop import CALIBRATION_DIR

__all__ = ["calibration_queries", "answer_at", "floor_table", "main"]

_KINDS = QUERY_KINDS[:-1]  # every kind but "absent"


def calibration_queries(args: tuple[str, str, int, int, int, bool]) -> list[dict]:
    """``(scene file, encoder, frames, width, height, drop_support)`` -> the scene's query entries
    without the floor, with ``regions``."""
    from harness.maps.query_open import score_open_query_scene
    from sim_envs.scenes.sealed import refuse_sealed
    from sim_envs.scenes.format import load_scene

    path, encoder, frames, width, height, drop_support = args
    refuse_sealed(path, "python -m harness.maps.query_open_develop")
    _, extras, _ = score_open_query_scene(load_scene(path), encoder, frames=frames, width=width, height=height,
                                          floor=False, all_regions=True, drop_support=drop_support)
    return extras["queries"]


def answer_at(entry: dict, floor: float | None) -> tuple[bool, float]:
    """``(found, IoU)`` of a query entry (with ``regions``) had the answer been floored at
    ``floor`` (None: no floor); IoU 0 for absent queries and answers not found."""
    for region in entry.get("regions") or ():
        if floor is None or region[0] >= floor:
            return True, (region[1] if len(region) > 1 else 0.0)
    return False, 0.0


def _auc(present: list[float], absent: list[float]) -> float:
    p, a = np.asarray(present, float), np.asarray(absent, float)
    if not len(p) or not len(a):
        return float("nan")
    return float(((p[:, None] > a[None]) + 0.5 * (p[:, None] == a[None])).mean())


def _best(entry: dict) -> float:
    return entry["regions"][0][0] if entry.get("regions") else -np.inf


def floor_table(entries: list[dict], floor: float | None) -> dict:
    """Found rate and mIoU per kind (``all``: every present query), IoU of the found answers,
    and ``absent_found``, at ``floor``."""
    out: dict = {}
    present = [e for e in entries if e["kind"] != "absent"]
    for kind in (*_KINDS, "all"):
        rows = [answer_at(e, floor) for e in present if kind == "all" or e["kind"] == kind]
        if rows:
            found = [f for f, _ in rows]
            ious = [i for _, i in rows]
            out[kind] = {"n": len(rows), "found": float(np.mean(found)), "miou": float(np.mean(ious)),
                         "iou_found": float(np.mean([i for f, i in rows if f])) if any(found) else float("nan")}
    absent = [answer_at(e, floor)[0] for e in entries if e["kind"] == "absent"]
    out["absent_found"] = float(np.mean(absent)) if absent else float("nan")
    out["n_absent"] = len(absent)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m harness.maps.query_open_develop", description=__doc__.splitlines()[0])
    p.add_argument("--tables", type=int, default=24, help="first N calibration tables (default: as many as the suite's 24)")
    p.add_argument("--encoder", default="embedded-v2")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--frames", type=int, default=12, help="scan frames (the suite's default: 12)")
    p.add_argument("--width", type=int, default=SCAN_SIZE[0], help=f"scan width (the suite's default: {SCAN_SIZE[0]})")
    p.add_argument("--height", type=int, default=SCAN_SIZE[1], help=f"scan height (the suite's default: {SCAN_SIZE[1]})")
    p.add_argument("--whole-regions", action="store_true",
                   help="answer with whole regions, the surface under an object included (MapperConfig.drop_support=False)")
    args = p.parse_args(argv)
    if min(args.tables, args.workers, args.frames) < 1 or min(args.width, args.height) < 8:
        p.error(f"expected --tables, --workers, --frames >= 1 and an image of at least 8x8, got {args.tables}, "
                f"{args.workers}, {args.frames}, {args.width}x{args.height}")
    from agents.builtin import make_mapper
    from tower_training.score_floor import choose_floor

    scenes = sorted(CALIBRATION_DIR.glob("tabletop-v2-*.json"))[: args.tables]
    if not scenes:
        p.error(f"no calibration tables in {CALIBRATION_DIR}")
    with ProcessPoolExecutor(args.workers) as pool:
        entries = [e for qs in pool.map(calibration_queries, [(str(s), args.encoder, args.frames, args.width, args.height, not args.whole_regions)
                                                       for s in scenes]) for e in qs]
    floor = make_mapper(args.encoder, "rgbd").config.min_score
    present = [_best(e) for e in entries if e["kind"] != "absent"]
    absent = [_best(e) for e in entries if e["kind"] == "absent"]
    print(f"{len(scenes)} calibration tables, {args.frames} frames at {args.width}x{args.height}, encoder {args.encoder}"
          f"{', whole regions' if args.whole_regions else ''}: "
          f"{len(present)} present queries, {len(absent)} absent")
    print(f"ROC AUC of the best region's median score, present vs absent: {_auc(present, absent):.3f}")
    chosen = choose_floor(present, absent)
    print(f"floor by balanced accuracy on these queries: {chosen:.3f}; the encoder's floor: {floor}")
    for label, f in (("encoder's floor", floor), ("no floor", None)):
        t = floor_table(entries, f)
        print(f"{label}: absent reported found {t['absent_found']:.2f} ({t['n_absent']})")
        for kind in (*_KINDS, "all"):
            if kind in t:
                r = t[kind]
                print(f"  {kind:9s} n {r['n']:4d}  found {r['found']:.2f}  mIoU {r['miou']:.3f}  IoU of found {r['iou_found']:.3f}")
    print("floor sweep: floor, present found, mIoU, absent found")
    finite = np.asarray([s for s in present + absent if np.isfinite(s)])
    for f in np.round(np.quantile(finite, np.linspace(0.05, 0.95, 10)), 3) if len(finite) else ():
        t = floor_table(entries, float(f))
        print(f"  {f:.3f}  {t['all']['found']:.2f}  {t['all']['miou']:.3f}  {t['absent_found']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
