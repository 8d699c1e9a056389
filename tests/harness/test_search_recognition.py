"""The search diagnosis (``benchmarks/bench_search_recognition.py``): the goal's rank among the objects
in the map, from ground-truth boxes and the map's scores."""

from __future__ import annotations

import collections
import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_search_recognition.py"
spec = importlib.util.spec_from_file_location("search_recognition", _PATH)
search_recognition = importlib.util.module_from_spec(spec)
spec.loader.exec_module(search_recognition)


def _mapper(points, scores):
    points, scores = np.asarray(points, np.float64), np.asarray(scores, np.float32)
    return SimpleNamespace(map=SimpleNamespace(points=points, scores_many=lambda q: scores[None]),
                           text_vector=lambda text: np.ones(4, np.float32))


def _cluster(centre, n, rng):
    return np.asarray(centre) + rng.uniform(-0.03, 0.03, (n, 3))


def test_goal_rank_counts_objects_that_score_higher():
    rng = np.random.default_rng(0)
    boxes = np.array([[[x - 0.1, -0.1, 0.7], [x + 0.1, 0.1, 0.9]] for x in (0.0, 1.0, 2.0, 3.0)])
    pts = np.concatenate([_cluster((0.0, 0, 0.8), 30, rng), _cluster((1.0, 0, 0.8), 30, rng),
                          _cluster((2.0, 0, 0.8), 30, rng), _cluster((3.0, 0, 0.8), 5, rng)])
    scores = np.concatenate([np.full(30, 0.2), np.full(30, 0.3), np.full(30, 0.1), np.full(5, 0.9)])
    scores[:10] = np.nan  # featureless points do not count
    m = _mapper(pts, scores)
    # Object 3 has too few points to be in the map; the goal (0) is beaten by object 1 only.
    assert search_recognition.goal_rank(m, "goal", boxes, 0) == {"rank": 2, "objects_in_map": 3, "goal_points": 20}
    assert search_recognition.goal_rank(m, "goal", boxes, 1)["rank"] == 1
    assert search_recognition.goal_rank(m, "goal", boxes, 2)["rank"] == 3
    assert search_recognition.goal_rank(m, "goal", boxes, 3) == {"rank": None, "objects_in_map": 3, "goal_points": 5}


def test_goal_rank_of_an_empty_map():
    boxes = np.array([[[0, 0, 0], [1, 1, 1]]], np.float64)
    assert search_recognition.goal_rank(_mapper(np.zeros((0, 3)), np.zeros(0)), "goal", boxes, 0) == \
        {"rank": None, "objects_in_map": 0, "goal_points": 0}


@pytest.mark.parametrize("argv", [["--limit", "0"], ["--at", "0"], ["--every", "0"]])
def test_bad_counts_are_refused(argv, capsys):
    with pytest.raises(SystemExit):
        search_recognition.main(argv)
    assert "expected integers >= 1" in capsys.readouterr().err


def test_recall_and_naming_by_object_size():
    import collections

    seg = np.full((20, 20), -1)
    seg[0:2, 0:3] = 0    # 6 pixels: no mask matches it
    seg[5:10, 5:10] = 1  # 25 pixels: matched, named right
    seg[12:20, 0:8] = 2  # 64 pixels: matched, named wrong
    masks = np.zeros((3, 20, 20), bool)
    masks[0, 5:10, 5:10] = True
    masks[1, 12:20, 0:8] = True
    masks[2, 0:1, 10:20] = True  # matches nothing
    proposer = SimpleNamespace(propose=lambda rgb, depth, K: masks)
    names = ["cup", "mug", "spoon"]
    vecs = np.eye(3, dtype=np.float32)
    # The encoder answers "mug" for every crop: right for object 1 (a mug), wrong for object 2.
    encoder = SimpleNamespace(encode_image=lambda crops: np.tile(vecs[1], (len(crops), 1)))
    obs = {"rgb": np.zeros((20, 20, 3), np.uint8), "depth": np.ones((20, 20), np.float32), "K": np.eye(3)}
    buckets, goal_pixels = collections.defaultdict(lambda: [0, 0, 0]), []
    search_recognition._recall(proposer, obs, seg, buckets, goal_pixels, 1, (encoder, names, vecs), ["spoon", "mug", "cup"])
    assert dict(buckets) == {2: [1, 0, 0], 4: [1, 1, 1], 6: [1, 1, 0]}
    assert goal_pixels == [25]
    lines = search_recognition.summary({"rows": [], "buckets": dict(buckets), "goal_pixels": goal_pixels}, 200)
    assert "objects of 16-31 pixels: 1 in view, proposer recall@0.5 1.00, named right" in "\n".join(lines)
    assert "goal in view: 1 frames, median 25 pixels" in lines[-1]


def test_isolated_features_keep_only_pixels_a_mask_isolates_the_object_of():
    seg = np.full((20, 20), -1)
    seg[2:6, 2:6] = 0     # isolated by mask 0
    seg[10:12, 10:12] = 1  # only inside mask 1, which is mostly background (IoU 4/100)
    masks = np.zeros((2, 20, 20), bool)
    masks[0, 2:6, 2:6] = True
    masks[1, 8:18, 8:18] = True
    rng = np.random.default_rng(0)

    def encode_image(images):
        v = rng.normal(size=(len(images), 8)).astype(np.float32)
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    featurizer = SimpleNamespace(proposer=SimpleNamespace(propose=lambda rgb, depth, K: masks),
                                 encoder=SimpleNamespace(encode_image=encode_image, dim=8), uniqueness=True, mode="full")
    obs = {"rgb": np.zeros((20, 20, 3), np.uint8), "depth": np.ones((20, 20), np.float32), "K": np.eye(3)}
    feats = search_recognition.isolated_features(featurizer, obs, seg)
    assert feats.index_hw.shape == (20, 20)
    assert np.all(feats.index_hw[2:6, 2:6] >= 0)
    kept = feats.index_hw >= 0
    assert kept.sum() == 16  # object 1, mask 1's background and unmasked pixels lose their features


def test_compared_proposers_report_their_own_recall():
    seg = np.full((20, 20), -1)
    seg[2:6, 2:6] = 0     # 16 pixels
    seg[10:18, 10:18] = 1  # 64 pixels
    one = np.zeros((1, 20, 20), bool)
    one[0, 10:18, 10:18] = True  # finds object 1 only
    both = np.concatenate([one, np.zeros((1, 20, 20), bool)])
    both[1, 2:6, 2:6] = True
    obs = {"rgb": np.zeros((20, 20, 3), np.uint8), "depth": np.ones((20, 20), np.float32), "K": np.eye(3)}
    compare = {}
    for spec, masks in (("one", one), ("both", both)):
        buckets = collections.defaultdict(lambda: [0, 0, 0])
        search_recognition._recall(SimpleNamespace(propose=lambda rgb, depth, K, m=masks: m), obs, seg, buckets, [], 0)
        compare[spec] = dict(buckets)
    lines = search_recognition.summary({"rows": [], "buckets": {}, "goal_pixels": [], "compare": compare}, 200)
    assert "one: proposer recall@0.5 16-31 px 0.00, 64-127 px 1.00" in lines
    assert "both: proposer recall@0.5 16-31 px 1.00, 64-127 px 1.00" in lines
