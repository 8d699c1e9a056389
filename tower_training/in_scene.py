"""In-scene retrieval on the validation tables: can a name pick its own object among a table's?

Crop-to-name retrieval among every library name (:mod:`tower_training.evaluate_v2`) asks the
tower to *name* a crop; an agent told to push "the kettle" only has to tell which of the few
things on its table is the kettle. This measures that, and what the generic phrases of a map
query (:data:`conceptfusion.map.query.NEGATIVE_PHRASES`) do to it, on VALIDATION views only
(``tower_val`` arrangements: held-out instances of trained categories and the validation
categories, which no training caption names), so it may guide agent design:

- ``in_scene_top1``: per object crop of a view (ground-truth boxes), the crop among that view's
  object and background crops that scores highest for the object's category name is one of its
  category's;
- ``beats_generics``: the object's own crop scores at least the relevancy margin (the query's
  ``relevancy_threshold`` 0.6 at temperature 10: 0.0405) above its best generic phrase, the
  test a map query's points must pass before the score floor.

Both split by trained categories (``train``, the validation instances of seen categories) and
validation categories (``val``). The views are the validation arrangements rendered on their own
(``DataConfigV2(train_scenes=0, test_scenes=0)``: 60 scenes, 4 views each, 13 s)::

    python -m tower_training.in_scene [--tower-dir DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from tower_training.data import default_cache_dir

__all__ = ["in_scene_figures", "main"]

RELEVANCY_MARGIN = math.log(0.6 / 0.4) / 10.0
"""Score margin over the best generic phrase at which a point's relevancy reaches 0.6 (the
query's default ``relevancy_threshold``, temperature 10)."""


def in_scene_figures(embed_fn, text_encoder, data, split, catalogue_) -> dict:
    """The figures of the module docstring for the crops ``data`` (a :class:`~tower_training.data.CropData`).

    Args:
        embed_fn: images -> (n, d) embeddings; ``text_encoder``: has ``encode_text``.
    """
    from conceptfusion.map.query import NEGATIVE_PHRASES
    from tower_training.data import SOURCES

    def unit(x):
        x = np.asarray(x, np.float32)
        return x / np.linalg.norm(x, axis=1, keepdims=True)

    names = np.array(data.class_names, dtype=object)[data.labels]
    obj = (data.sources == SOURCES.index("gt")) & np.isin(names, list(catalogue_.instances))
    idx = np.flatnonzero(obj | (data.sources == SOURCES.index("background")))
    emb = unit(embed_fn([data.images[i] for i in idx]))
    cats = sorted(split.categories)
    col = {c: i for i, c in enumerate(cats)}
    scores = emb @ unit(text_encoder.encode_text(cats)).T
    generic = (emb @ unit(text_encoder.encode_text(list(NEGATIVE_PHRASES))).T).max(axis=1)
    is_obj, views = obj[idx], data.views[idx]
    category = np.array([catalogue_.instances[n].category if n in catalogue_.instances else "" for n in names[idx]], dtype=object)
    tally = {k: {"n": 0, "in_scene_top1": 0, "picked_background": 0, "beats_generics": 0} for k in ("train", "val")}
    for v in np.unique(views):
        rows = np.flatnonzero(views == v)
        for r in rows[is_obj[rows]]:
            c = category[r]
            t = tally[split.categories[c]]
            own = scores[r, col[c]]
            winner = rows[np.argmax(scores[rows, col[c]])]
            t["n"] += 1
            t["in_scene_top1"] += int(category[winner] == c)
            t["picked_background"] += int(not is_obj[winner])
            t["beats_generics"] += int(own - generic[r] >= RELEVANCY_MARGIN)
    return {k: {"n": t["n"], **{m: round(t[m] / t["n"], 4) for m in t if m != "n"}} if t["n"] else t for k, t in tally.items()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tower_training.in_scene", description=__doc__.splitlines()[0])
    p.add_argument("--tower-dir", default=None, help="exported tower folder (default: the shipped v2 tower)")
    p.add_argument("--cache-dir", default=default_cache_dir(),
                   help="where rendered crops are cached")
    args = p.parse_args(argv)
    from conceptfusion.perception.image_tower import EmbeddedEncoder
    from conceptfusion.perception.text_tower import MiniLMTextEncoder
    from sim_envs.assets.library import catalogue
    from sim_envs.scenes.splits import splits
    from tower_training.world_v2 import DataConfigV2, render_crop_data_v2

    tower_dir = Path(args.tower_dir) if args.tower_dir else Path(__file__).resolve().parents[1] / "conceptfusion" / "data" / "embedded_tower_v2"
    data = render_crop_data_v2(DataConfigV2(train_scenes=0, test_scenes=0), Path(args.cache_dir))
    text = MiniLMTextEncoder()
    enc = EmbeddedEncoder(tower_dir, text)
    figures = in_scene_figures(lambda ims: enc.encode_image(list(ims)), text, data, splits(), catalogue())
    print(json.dumps({"tower_dir": str(tower_dir), "validation": figures}, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
