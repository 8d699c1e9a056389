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
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from conceptfusion.tower_data import BACKGROUND_CLASS, SOURCES, CropData, ObjectClass

__all__ = ["top1", "evaluate_crops"]


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
