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

Its command line calibrates the tower's **score floor** (:mod:`tower_training.score_floor`):
``python -m tower_training.evaluate --calibrate-floor`` measures it on reserved shipped tabletop
scenes (``--world v2``: library arrangements of calibration seeds) and writes it into the
tower's ``tower.json`` (``metrics.score_floor``); ``--frames`` and ``--size`` set the orbit scans
(default 12 frames of 160x120), ``--dry-run`` only prints.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from typing import Callable, Sequence

import numpy as np

from tower_training.data import BACKGROUND_CLASS, SOURCES, CropData, ObjectClass
from tower_training.score_floor import FloorConfig, FloorConfigV2, calibrate_score_floor, calibrate_score_floor_v2, write_score_floor

__all__ = ["top1", "evaluate_crops", "main"]


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


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m tower_training.evaluate",
                                description="Evaluate the embedded image tower in maps.")
    p.add_argument("--calibrate-floor", action="store_true",
                   help="measure map-query scores on shipped tabletop scenes, choose the score floor and write it into tower.json")
    p.add_argument("--tower-dir", default=None, help="tower folder (default: the shipped tower)")
    p.add_argument("--dry-run", action="store_true", help="print the calibration, write nothing")
    p.add_argument("--world", choices=("v1", "v2"), default="v1",
                   help="v1: shipped tabletop scenes (default); v2: library arrangements of the calibration seeds")
    p.add_argument("--frames", type=int, default=FloorConfig.frames, help="frames of each orbit scan (default %(default)s)")
    p.add_argument("--size", default=f"{FloorConfig.width}x{FloorConfig.height}",
                   help="scan image size WIDTHxHEIGHT (default %(default)s)")
    return p


def parse_image_size(parser: argparse.ArgumentParser, size: str) -> tuple[int, int]:
    """A ``--size`` argument ``WIDTHxHEIGHT`` as ``(width, height)`` pixels (a parser error naming
    what arrived otherwise)."""
    w, _, h = size.lower().partition("x")
    if not (w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
        parser.error(f"--size: expected WIDTHxHEIGHT in pixels such as 320x240, got {size!r}")
    return int(w), int(h)


def _scan_config(parser: argparse.ArgumentParser, frames: int, size: str) -> dict:
    """``--frames`` and ``--size`` as :class:`FloorConfig` fields (a parser error naming what arrived otherwise)."""
    w, h = parse_image_size(parser, size)
    if frames < 1:
        parser.error(f"--frames: expected at least 1, got {frames}")
    return {"frames": frames, "width": w, "height": h}


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if not args.calibrate_floor:
        parser.print_help()
        return 2
    scan = _scan_config(parser, args.frames, args.size)
    encoder = None
    if args.tower_dir is not None:
        from conceptfusion.perception.registry import make_encoder

        encoder = make_encoder(f"embedded:{args.tower_dir}")
    t0 = time.perf_counter()
    if args.world == "v2":
        result = calibrate_score_floor_v2(FloorConfigV2(scan=FloorConfig(calibration_scenes=(), validation_scenes=(), **scan)), encoder=encoder)
    else:
        result = calibrate_score_floor(dataclasses.replace(FloorConfig(), **scan), encoder=encoder)
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
