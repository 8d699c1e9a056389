"""Retrieval metrics of the v2 tower on crops of object-library arrangements.

Every metric is top-1 (or top-5) crop-to-text retrieval over crops of objects (ground-truth and
matched proposer crops, :data:`tower_training.data.SOURCES`), with texts as a user types them:

* ``name``: among ALL library category names (91: "mug", "wine glass", ...; train, val and
  test categories alike); right when the crop's category wins;
* ``synonym``: for each synonym s of the crop's category, the 91 names with the category's own
  name replaced by s; right when s wins (mean over crops and synonyms; a synonym that is another
  category's name, "cup" for a mug, is skipped);
* ``colour_name``: "a <crop's colour> <name>" for each of the 91 names; right when the crop's
  category wins (same task as ``name``, with the colour word in every query);
* ``colour_name_pairs``: among every distinct colour + category pair of the library's instances
  ("a red mug", ...); right when the crop's own pair wins (colour and category both right);
* ``parent``: among every group name of the taxonomy but the root; right when the winner is an
  ancestor of the crop's category;
* ``function``: among every distinct function phrase; right when the winner is one of its
  category's.

Sets (by the split file's roles and the view set of the crop's scene,
:data:`tower_training.world_v2.SETS`): ``seen_unseen_view`` (TRAIN instances in test views),
``held_out_instances`` (TEST instances of TRAIN categories), ``held_out_categories`` (instances of
TEST categories), and the validation sets ``val_instances`` / ``val_categories`` (VAL views).
:func:`val_selection_fn` is the model-selection score: name top-1 over all validation crops.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from sim_envs.assets.library import catalogue
from sim_envs.scenes.splits import Splits
from tower_training.captions import article
from tower_training.data import BACKGROUND_CLASS, SOURCES, CropData
from tower_training.training import half_res, name_top1

__all__ = ["crop_sets", "topk", "evaluate_crops_v2", "val_selection_inputs", "val_selection_fn"]


def topk(emb_nd: np.ndarray, texts_td: np.ndarray, correct_nt: np.ndarray, k: int = 1) -> float:
    """Fraction of rows with a correct text among their ``k`` best (NaN for no rows).

    Shape:
        (n, d), (T, d), (n, T) bool -> float.
    """
    if len(emb_nd) == 0:
        return float("nan")
    order = np.argsort(-(emb_nd @ texts_td.T), axis=1)[:, :k]
    return float(np.mean(np.take_along_axis(correct_nt, order, axis=1).any(axis=1)))


def crop_sets(data: CropData, split: Splits, set_seeds: dict[str, list[int]]) -> dict[str, np.ndarray]:
    """Boolean masks (n,) of the evaluation and validation sets (see the module docstring).

    Args:
        set_seeds: ``{"val": seeds, "test": seeds}`` of the view sets.
    """
    cat = catalogue()
    names = np.array(data.class_names, dtype=object)[data.labels]
    is_obj = np.isin(data.sources, [SOURCES.index("gt"), SOURCES.index("proposer")]) & np.isin(names, list(cat.instances))
    inst_role = np.array([split.instances.get(n, "") for n in names], dtype=object)
    cat_role = np.array([split.categories.get(cat.instances[n].category, "") if n in cat.instances else "" for n in names],
                        dtype=object)
    test = np.isin(data.seeds, set_seeds["test"])
    val = np.isin(data.seeds, set_seeds["val"])
    return {
        "seen_unseen_view": is_obj & test & (inst_role == "train"),
        "seen_unseen_view_gt_crops": is_obj & test & (inst_role == "train") & (data.sources == SOURCES.index("gt")),
        "seen_unseen_view_proposer_crops": is_obj & test & (inst_role == "train") & (data.sources == SOURCES.index("proposer")),
        "held_out_instances": is_obj & test & (inst_role == "test") & (cat_role == "train"),
        "held_out_categories": is_obj & test & (cat_role == "test"),
        "val_instances": is_obj & val & (inst_role == "val") & (cat_role == "train"),
        "val_categories": is_obj & val & (cat_role == "val"),
    }


def _embed(embed_fn, data: CropData, mask: np.ndarray) -> np.ndarray:
    idx = np.flatnonzero(mask)
    return np.asarray(embed_fn([data.images[i] for i in idx]), np.float32) if len(idx) else np.zeros((0, 1), np.float32)


def val_selection_inputs(text_encoder, data: CropData, split: Splits, val_seeds: list[int]):
    """What the model-selection score needs: every validation crop (VAL instances of train
    categories and VAL categories, VAL views only), its category's row among all library
    category names (sorted), and those names' text embeddings.

    Shape:
        -> (n crops (h_i, w_i, 3) uint8, truth (n,) int64, names (91, d) float32).
    """
    cat = catalogue()
    sets = crop_sets(data, split, {"val": val_seeds, "test": []})
    idx = np.flatnonzero(sets["val_instances"] | sets["val_categories"])
    cats = sorted(cat.categories)
    t_names = np.asarray(text_encoder.encode_text(cats), np.float32)
    truth = np.array([cats.index(cat.instances[data.class_names[data.labels[i]]].category) for i in idx], np.int64)
    return [data.images[i] for i in idx], truth, t_names


def val_selection_fn(text_encoder, data: CropData, split: Splits, val_seeds: list[int], *,
                     half_res_too: bool = False) -> Callable:
    """``select(embed_fn) -> float``: name top-1 among all library category names over every
    validation crop (:func:`val_selection_inputs`, :func:`tower_training.training.name_top1`);
    with ``half_res_too``, the mean of that and the same figure on the crops at half resolution
    (:func:`tower_training.training.half_res`)."""
    images, truth, t_names = val_selection_inputs(text_encoder, data, split, val_seeds)
    image_sets = [images] + ([half_res(images)] if half_res_too else [])
    return lambda embed_fn: name_top1(embed_fn, image_sets, truth, t_names)


def evaluate_crops_v2(embed_fn, text_encoder, data: CropData, split: Splits, set_seeds: dict[str, list[int]],
                      *, include_test: bool = True) -> dict:
    """Every v2 metric of the model card: ``{"<set>/<metric>": {"top1": float, "n": int}}``
    (``held_out_categories/name`` also has ``top5``).

    Args:
        embed_fn: crops -> (n, d) unit rows.
        include_test: False measures the validation sets only (test crops are not embedded).
    """
    cat = catalogue()
    cats = sorted(cat.categories)
    groups = sorted(g for g in cat.groups if g != "object")
    functions = sorted({f for c in cat.categories.values() for f in c.functions})
    pairs = sorted({(i.color, i.category) for i in cat.instances.values()})
    enc = lambda texts: np.asarray(text_encoder.encode_text(list(texts)), np.float32)  # noqa: E731
    t_names, t_groups, t_funcs = enc(cats), enc(groups), enc(functions)
    t_pairs = enc(article(f"{c} {n}") for c, n in pairs)
    t_syn = {s: e for s, e in zip(sorted({s for c in cat.categories.values() for s in c.synonyms}),
                                 enc(sorted({s for c in cat.categories.values() for s in c.synonyms})))}
    colours = sorted({i.color for i in cat.instances.values()})
    t_col_names = {c: enc(article(f"{c} {n}") for n in cats) for c in colours}

    sets = crop_sets(data, split, set_seeds)
    if not include_test:
        sets = {k: v for k, v in sets.items() if k.startswith("val_")}
    out: dict[str, dict] = {}
    names = np.array(data.class_names, dtype=object)
    for key, mask in sets.items():
        rows = np.flatnonzero(mask)
        e = _embed(embed_fn, data, mask)
        insts = [cat.instances[names[data.labels[r]]] for r in rows]
        ci = np.array([cats.index(i.category) for i in insts], np.int64)
        onehot = np.zeros((len(rows), len(cats)), bool)
        onehot[np.arange(len(rows)), ci] = True
        n = len(rows)
        out[f"{key}/name"] = {"top1": topk(e, t_names, onehot), "n": n}
        if key in ("held_out_categories", "val_categories"):
            out[f"{key}/name"]["top5"] = topk(e, t_names, onehot, 5)
            # among the held-out categories only (how well their names are told apart)
            held = sorted({i.category for i in insts})
            hi = np.array([cats.index(h) for h in held], np.int64)
            out[f"{key}/name_among_held_out"] = {"top1": topk(e, t_names[hi], onehot[:, hi]), "n": n,
                                                 "candidates": len(held)}
        if key in ("seen_unseen_view", "held_out_instances", "held_out_categories", "val_instances"):
            # the same crops as a 160x120 frame shows them
            e_half = np.asarray(embed_fn(half_res([data.images[r] for r in rows])), np.float32) if n else e
            out[f"{key}/name_half_res"] = {"top1": topk(e_half, t_names, onehot), "n": n}
            if key == "held_out_categories":
                out[f"{key}/name_half_res"]["top5"] = topk(e_half, t_names, onehot, 5)
        if not key.startswith("seen_unseen_view") and key != "held_out_instances":
            continue
        # query kinds on seen objects (and held-out instances)
        syn_hits, syn_n = 0.0, 0
        for j in range(n):
            c = cat.categories[insts[j].category]
            if e.shape[1] != t_names.shape[1] or not c.synonyms:
                continue
            s_names = e[j] @ t_names.T
            others = np.delete(s_names, ci[j])
            best_other = others.max()
            for s in c.synonyms:
                if s in cat.categories:  # "cup" is a synonym of mug and a category of its own
                    continue
                syn_hits += float(e[j] @ t_syn[s] > best_other)
                syn_n += 1
        out[f"{key}/synonym"] = {"top1": syn_hits / syn_n if syn_n else float("nan"), "n": syn_n}
        col_hits = [int(np.argmax(t_col_names[i.color] @ e[j]) == ci[j]) for j, i in enumerate(insts)]
        out[f"{key}/colour_name"] = {"top1": float(np.mean(col_hits)) if n else float("nan"), "n": n}
        ok = np.array([[p == (i.color, i.category) for p in pairs] for i in insts], bool).reshape(n, len(pairs))
        out[f"{key}/colour_name_pairs"] = {"top1": topk(e, t_pairs, ok), "n": n, "candidates": len(pairs)}
        anc = [set(cat.ancestors(i.category)) for i in insts]
        ok = np.array([[g in a for g in groups] for a in anc], bool).reshape(n, len(groups))
        out[f"{key}/parent"] = {"top1": topk(e, t_groups, ok), "n": n, "candidates": len(groups)}
        ok = np.array([[f in cat.categories[i.category].functions for f in functions] for i in insts],
                      bool).reshape(n, len(functions))
        out[f"{key}/function"] = {"top1": topk(e, t_funcs, ok), "n": n, "candidates": len(functions)}
    if include_test:
        bg = (data.sources == SOURCES.index("background")) & np.isin(data.seeds, set_seeds["test"])
        e = _embed(embed_fn, data, bg)
        cand = np.concatenate([t_names, enc([BACKGROUND_CLASS.phrases[0]])])
        ok = np.zeros((int(bg.sum()), len(cand)), bool)
        ok[:, -1] = True
        out["background_unseen_view/background"] = {"top1": topk(e, cand, ok), "n": int(bg.sum())}
    return out
