"""In-scene retrieval figures (``tower_training.in_scene``) on crops with known embeddings."""

from types import SimpleNamespace

import numpy as np

from conceptfusion.map.query import NEGATIVE_PHRASES
from tower_training.data import SOURCES, CropData
from tower_training.in_scene import RELEVANCY_MARGIN, in_scene_figures

AXES = ["mug", "jar", "bowl", *NEGATIVE_PHRASES]


def _unit(v):
    v = np.asarray(v, np.float32)
    return v / np.linalg.norm(v)


class _Text:
    """One axis per category name and per generic phrase."""

    def encode_text(self, texts):
        return np.stack([np.eye(len(AXES), dtype=np.float32)[AXES.index(t)] for t in texts])


def test_figures_count_in_scene_winners_background_picks_and_the_generic_margin():
    # view 0: a mug that wins its name and beats the generics; a jar (validation category) that
    # scores low for "jar" but still wins it in the scene, losing to "object";
    # view 1: a bowl whose name is won by the background crop.
    emb = {
        "mug": _unit([0.9, 0.0, 0.0, 0.3, 0, 0, 0]),
        "jar": _unit([0.0, 0.2, 0.0, 0.5, 0, 0, 0]),
        "bg0": _unit([0.1, 0.05, 0.1, 0.2, 0, 0, 0]),
        "bowl": _unit([0.0, 0.0, 0.2, 0.1, 0, 0, 0.9]),
        "bg1": _unit([0.0, 0.0, 0.9, 0.1, 0, 0, 0]),
    }
    keys = ["mug", "jar", "bg0", "bowl", "bg1"]
    classes = ("mug-01", "jar-01", "bowl-01", "table or floor")
    labels = [0, 1, 3, 2, 3]
    sources = [SOURCES.index(s) for s in ("gt", "gt", "background", "gt", "background")]
    data = CropData([np.full((4, 4, 3), i, np.uint8) for i in range(5)], labels, sources, [0] * 5, [0, 0, 0, 1, 1], classes)
    cat = SimpleNamespace(instances={"mug-01": SimpleNamespace(category="mug"), "jar-01": SimpleNamespace(category="jar"),
                                     "bowl-01": SimpleNamespace(category="bowl")})
    split = SimpleNamespace(categories={"mug": "train", "bowl": "train", "jar": "val"})
    embed = lambda images: np.stack([emb[keys[int(im[0, 0, 0])]] for im in images])  # noqa: E731
    got = in_scene_figures(embed, _Text(), data, split, cat)
    assert got["val"] == {"n": 1, "in_scene_top1": 1.0, "picked_background": 0.0, "beats_generics": 0.0}
    assert got["train"] == {"n": 2, "in_scene_top1": 0.5, "picked_background": 0.5, "beats_generics": 0.5}
    assert emb["mug"][0] - emb["mug"][3] >= RELEVANCY_MARGIN  # the mug's margin, as counted
