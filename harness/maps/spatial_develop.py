"""Spatial-question settings chosen on calibration scenes, never on the suite's.

``python -m harness.maps.spatial_develop [--tables N] [--apartments N] [--encoder SPEC]``
answers the questions of the first N v2 calibration tables and apartments
(``scenes/calibration-v2/``: floor-calibration seeds, no evaluation scene) with the 3D map and the
single frame, with the questions' objects taken to be there (``assume_present`` and
``name_only_fallback``, the defaults) and without, and prints the accuracy per comparator. The
same scan, questions and scoring as ``spatial-v2`` (:func:`harness.maps.spatial.answer_questions`).
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor

from sim_envs.scenes.episodes import SCENES_ROOT

__all__ = ["answer_calibration_scene", "main"]

CALIBRATION_DIR = SCENES_ROOT / "calibration-v2"
"""The v2 calibration scenes (``python -m scenes.make_calibration_v2``), where map-suite settings are chosen."""
SETTINGS = {"assumed present": True, "as found": False}


def answer_calibration_scene(args: tuple[str, str, str, bool]) -> tuple[str, str, bool, list[tuple[str, bool]]]:
    """``(scene file, method, encoder, assume)`` -> the same with ``(comparator, correct)`` per question,
    scored as the suite scores a scene (:func:`~harness.maps.spatial.score_spatial_scene`, its defaults)."""
    from harness.maps.spatial import score_spatial_scene
    from sim_envs.scenes.sealed import refuse_sealed
    from sim_envs.scenes.format import load_scene

    path, method, encoder, assume = args
    refuse_sealed(path, "python -m harness.maps.spatial_develop")
    _, extras, _ = score_spatial_scene(load_scene(path), method, encoder, assume_present=assume, name_only_fallback=assume)
    return path, method, assume, [(q["type"], bool(q["correct"])) for q in extras["questions"]]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m harness.maps.spatial_develop", description=__doc__.splitlines()[0])
    p.add_argument("--tables", type=int, default=12)
    p.add_argument("--apartments", type=int, default=4)
    p.add_argument("--encoder", default="embedded-v2")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    if args.tables < 0 or args.apartments < 0 or args.workers < 1:
        p.error(f"expected --tables, --apartments >= 0 and --workers >= 1, got {args.tables}, {args.apartments}, {args.workers}")
    scenes = sorted(CALIBRATION_DIR.glob("tabletop-v2-*.json"))[: args.tables] + sorted(CALIBRATION_DIR.glob("household-v2-*.json"))[: args.apartments]
    if not scenes:
        p.error(f"no calibration scenes in {CALIBRATION_DIR}")
    jobs = [(str(s), m, args.encoder, a) for s in scenes for m in ("3d", "2.5d") for a in SETTINGS.values()]
    tally: dict = defaultdict(lambda: defaultdict(list))
    with ProcessPoolExecutor(args.workers) as pool:
        for _, method, assume, answers in pool.map(answer_calibration_scene, jobs):
            for kind, ok in answers:
                tally[(method, assume)][kind].append(ok)
    print(f"{len(scenes)} calibration scenes, encoder {args.encoder}")
    for (method, assume), kinds in sorted(tally.items()):
        flat = [ok for v in kinds.values() for ok in v]
        per = ", ".join(f"{k} {sum(v)}/{len(v)}" for k, v in sorted(kinds.items()))
        label = next(k for k, v in SETTINGS.items() if v == assume)
        print(f"{method:5s} {label:16s} {sum(flat)}/{len(flat)} = {sum(flat) / len(flat):.3f}  ({per})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
