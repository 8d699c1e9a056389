"""Vocabulary contrast: which candidate a name picks when each is scored against the names an
encoder was trained on (:func:`conceptfusion.map.query.vocabulary_margins`), and where an
encoder's vocabulary comes from (:func:`conceptfusion.perception.featurizer.encoder_vocabulary`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conceptfusion.errors import ShapeError
from conceptfusion.map.query import vocabulary_margins
from conceptfusion.map.regions import Region
from conceptfusion.perception.featurizer import encoder_vocabulary

DATA = Path(__file__).resolve().parents[2] / "conceptfusion" / "data"


def _unit(v):
    v = np.asarray(v, np.float32)
    return v / np.linalg.norm(v)


class _Map:
    """The parts of a PointFusionMap that vocabulary_margins reads: unit features per point."""

    def __init__(self, feats_nd, has_n=None) -> None:
        self.feats = np.asarray(feats_nd, np.float32)
        self.feature_dim = self.feats.shape[1]
        self.has_feature = np.ones(len(self.feats), bool) if has_n is None else np.asarray(has_n, bool)

    def check_query(self, q):
        q = np.asarray(q, np.float64)
        if q.shape != (self.feature_dim,):
            raise ShapeError(f"query_d: expected shape ({self.feature_dim},), got {q.shape}")
        return q

    def features(self, idx):
        return np.where(self.has_feature[idx, None], self.feats[idx], 0.0)


def _region(idx):
    idx = np.asarray(idx, np.int64)
    return Region(points_n3=np.zeros((len(idx), 3)), scores_n=np.zeros(len(idx), np.float32), indices_n=idx)


def test_a_thing_no_known_name_explains_beats_one_that_scores_higher_for_the_query():
    mug_name = _unit([1, 0, 0])
    query = _unit([0.5, 1, 0])  # a name that sits near "mug" in the text space
    mugish = _unit([1, 1, 0])  # a mug: scores 0.95 for the query, 0.71 for "mug"
    unknown = _unit([0, 0.9, 0.436])  # looks like nothing known: 0.80 for the query, 0 for "mug"
    fmap = _Map(np.stack([mugish] * 3 + [unknown] * 3))
    margins = vocabulary_margins(fmap, query, mug_name[None], [_region([0, 1, 2]), _region([3, 4, 5])])
    assert float(mugish @ query) > float(unknown @ query)  # the query alone would pick the mug
    assert margins == pytest.approx([float(mugish @ query - mugish @ mug_name), float(unknown @ query)], abs=1e-5)
    assert margins[1] > margins[0]


def test_the_median_over_points_decides_and_featureless_candidates_rank_last():
    a, b = _unit([1, 0]), _unit([0, 1])
    fmap = _Map(np.stack([a, a, b, b]), has_n=[True, True, True, False])
    # candidate 0: margins of its points (query a, vocabulary b): 1, 1, -1 -> median 1
    margins = vocabulary_margins(fmap, a, b[None], [_region([0, 1, 2]), _region([3])])
    assert margins[0] == pytest.approx(1.0) and margins[1] == -np.inf


def test_bad_input_says_what_was_expected():
    fmap = _Map(np.eye(3))
    with pytest.raises(ShapeError, match="at least one name"):
        vocabulary_margins(fmap, np.ones(3), np.zeros((0, 3)), [_region([0])])
    with pytest.raises(ShapeError, match="vocabulary_kd"):
        vocabulary_margins(fmap, np.ones(3), np.ones((2, 4)), [_region([0])])
    with pytest.raises(ValueError, match="point indices"):
        vocabulary_margins(fmap, np.ones(3), np.ones((1, 3)), [Region(np.zeros((1, 3)), np.zeros(1, np.float32))])
    with pytest.raises(ValueError, match="outside the map"):
        vocabulary_margins(fmap, np.ones(3), np.ones((1, 3)), [_region([5])])


def test_the_v2_tower_knows_its_train_categories_and_the_v1_tower_none():
    class _Enc:
        def __init__(self, info):
            self.info = info

    v2 = json.loads((DATA / "embedded_tower_v2" / "tower.json").read_text())
    v1 = json.loads((DATA / "embedded_tower" / "tower.json").read_text())
    vocab = encoder_vocabulary(_Enc(v2))
    assert vocab == tuple(sorted(v2["splits"]["categories"]["train"])) and len(vocab) >= 60
    assert not set(vocab) & set(v2["splits"]["categories"]["test"])  # held-out categories stay unknown
    assert encoder_vocabulary(_Enc(v1)) == () and encoder_vocabulary(object()) == ()
    with pytest.raises(ValueError, match="splits.categories.train"):
        encoder_vocabulary(_Enc({"splits": {"categories": {"train": ["mug", ""]}}}))
