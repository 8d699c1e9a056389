"""The ``oracle-open`` perception: ground-truth segmentation and ground-truth grounding of descriptions."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from agents.concept_map import ConceptMapper, MapperConfig, privileged_labels
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.featurizer import (
    ORACLE_OPEN, ORACLE_OPEN_MIN_SCORE, FrameFeaturizer, GroundedOracleFeaturizer, OracleFeaturizer, PerceptionSpec,
    is_oracle, make_featurizer, perception_names,
)
from conceptfusion.perception.oracle import GROUNDED_ORACLE_DIM, GroundedOracleFeatures, drop_small_segments, normalize_phrase
from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.synthetic import Box, orbit_poses, render_boxes
from sim_envs.assets.library import catalogue
from sim_envs.scenes.descriptions import DESCRIPTION_KINDS, answer_phrases, describable, referents
from sim_envs.scenes.format import SceneObject

V2 = Path(__file__).resolve().parents[2] / "scenes" / "tabletop-v2" / "episodes-v2.jsonl"


def _obj(i: int, instance_id: str) -> SceneObject:
    inst = catalogue().instances[instance_id]
    return SceneObject(f"obj{i}", inst.category, inst.category, inst.asset, inst.color, (0.0, 0.1 * i, 0.4), 0.0, (0.1, 0.1, 0.1))


# A black ceramic mug, a red metal hammer and a red plastic cup (the cup's name is a synonym of the mug's).
OBJECTS = [_obj(0, "mug-000"), _obj(1, "hammer-002"), _obj(2, "cup-000")]
PHRASES = {i: answer_phrases(o) for i, o in enumerate(OBJECTS)}


def test_descriptions_of_every_kind_reach_exactly_their_referents():
    g = GroundedOracleFeatures(PHRASES)
    assert g.privileged and g.dim == GROUNDED_ORACLE_DIM
    assert g.referents("the mug") == [0]                      # name
    assert g.referents("the mallet") == [1]                   # synonym
    assert g.referents("the black mug") == [0]                # colour + name
    assert g.referents("the ceramic mug") == [0]              # material + name
    assert g.referents("the metal hammer") == [1]
    assert g.referents("a tool to drive nails") == [1]        # function
    assert g.referents("the tool") == [1]                     # parent
    assert g.referents("the drinkware") == [0, 2]             # a parent of two objects
    assert g.referents("something to drink from") == [0, 2]
    assert g.referents("the cup") == [0, 2]                   # the cup's name, a synonym of the mug
    assert g.referents("the banana") == [] and g.referents("the red mug") == []
    # Normalised on both sides: case, spaces, a leading article.
    assert g.referents("  The   MALLET ") == g.referents("mallet") == g.referents("a mallet") == [1]
    assert normalize_phrase("  An  Apple ") == "apple" and normalize_phrase("the") == "the"
    # The same referents as the scene descriptions' ground truth, for every phrase of every kind.
    for obj in OBJECTS:
        for kind in DESCRIPTION_KINDS:
            for text in describable(obj).phrases(kind):
                assert g.referents(text) == [OBJECTS.index(o) for o in referents(text, OBJECTS)], text


def test_query_vectors_are_referent_codes_or_the_reserved_vector():
    g = GroundedOracleFeatures(PHRASES)
    q = g.encode_text(["the mallet", "the drinkware", "the banana"])
    assert q.shape == (3, GROUNDED_ORACLE_DIM) and q.dtype == np.float32
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert q[0, 1] == 1.0 and np.count_nonzero(q[0]) == 1
    assert np.allclose(q[1, [0, 2]], 1 / math.sqrt(2)) and np.count_nonzero(q[1]) == 2
    assert q[2, -1] == 1.0 and np.count_nonzero(q[2]) == 1  # nothing answers: the reserved vector
    seg = np.array([[0, 1, -1], [2, 9, 1]])
    dense = g(seg).dense()
    scores = dense @ q[1]
    assert np.allclose(scores, [[1 / math.sqrt(2), 0, 0], [1 / math.sqrt(2), 0, 0]])
    assert np.all(dense[0, 2] == 0) and np.all(dense[1, 1] == 0)  # background and an unlabelled id
    assert np.all(dense.reshape(-1, GROUNDED_ORACLE_DIM) @ q[2] == 0)  # the reserved vector scores 0 everywhere
    # The floor sits below every referent's score and above the non-referents' 0.
    assert 0 < ORACLE_OPEN_MIN_SCORE < 1 / math.sqrt(GROUNDED_ORACLE_DIM - 1)


def test_bad_labels_and_phrases_raise_clear_errors():
    with pytest.raises(ValueError, match=r"ids below 255 .*got id 255"):
        GroundedOracleFeatures({0: ["the mug"], 255: ["the cup"]})
    with pytest.raises(ValueError, match=r"ids below 7 .*got id 7"):
        GroundedOracleFeaturizer(dim=8).reset(label_phrases={7: ["the mug"]})
    with pytest.raises(ValueError, match="ids >= 0"):
        GroundedOracleFeatures({-1: ["the mug"]})
    with pytest.raises(ValueError, match="at least one"):
        GroundedOracleFeatures({})
    with pytest.raises(TypeError, match="collection of phrases, got the string 'the mug'"):
        GroundedOracleFeatures({0: "the mug"})
    f = GroundedOracleFeaturizer()
    with pytest.raises(RuntimeError, match=r"call reset\(label_phrases=...\) before encode_text"):
        f.encode_text(["the mug"])
    with pytest.raises(ValueError, match=r"expected the phrases each object answers to .*label_phrases.*object_phrases"):
        f.reset({0: "mug"})
    mapper = ConceptMapper(f)
    with pytest.raises(ValueError, match="label_phrases"):
        mapper.reset({0: "mug"})  # names alone do not ground descriptions
    f.reset(label_phrases=PHRASES)
    frame = _frames(_boxes([0, 1, 2]), n=1)[0]
    assert f.features(frame).dense().shape == frame.depth.shape + (GROUNDED_ORACLE_DIM,)
    with pytest.raises(ValueError, match="expected the frame's segmentation"):
        f.features(dataclasses.replace(frame, segmentation=None))


def test_the_spec_factory_and_protocol():
    assert ORACLE_OPEN == "oracle-open" and ORACLE_OPEN in perception_names()
    spec = PerceptionSpec.parse("oracle-open")
    assert str(spec) == "oracle-open" and spec.encoder_name == ORACLE_OPEN
    for bad in ("oracle-open:x", "oracle-open:min_pixels=-1", "oracle-open:min_pixels=2.5", "oracle-open:size=20"):
        with pytest.raises(ValueError, match=r"encoder 'oracle-open': expected no argument or 'min_pixels=N'"):
            PerceptionSpec.parse(bad)
    with pytest.raises(ValueError, match="did you mean 'oracle-open'"):
        PerceptionSpec.parse("oracle-opne")
    f = make_featurizer("oracle-open")
    assert isinstance(f, GroundedOracleFeaturizer) and isinstance(f, FrameFeaturizer)
    assert f.privileged and f.scene_dependent_text and f.score_floor == ORACLE_OPEN_MIN_SCORE
    assert f.encoder.dim == f.dim == GROUNDED_ORACLE_DIM
    assert not hasattr(f.encoder, "encode_image")  # text only: image queries are refused by their callers
    f.reset(label_phrases=PHRASES)
    assert np.array_equal(f.encoder.encode_text(["the tool"]), f.encode_text(["the tool"]))


def test_min_pixels_leaves_segments_smaller_than_it_without_a_feature():
    spec = PerceptionSpec.parse("oracle-open:min_pixels=5")
    assert spec.privileged and spec.oracle_min_pixels == 5 and PerceptionSpec.parse("oracle-open").oracle_min_pixels == 0
    assert is_oracle("oracle-open:min_pixels=5") and is_oracle("oracle") and not is_oracle("embedded-v2")
    f = make_featurizer(spec)
    assert f.min_pixels == 5
    f.reset(label_phrases=PHRASES)
    seg = np.full((6, 8), -1, np.int64)
    seg[0:2, 0:3] = 0  # 6 pixels: kept
    seg[4, 0:4] = 1    # 4 pixels: too small
    seg[5, 7] = 2      # 1 pixel: too small
    frame = _frames(_boxes([0, 1, 2]), n=1)[0]
    frame = dataclasses.replace(frame, rgb=frame.rgb[:6, :8], depth=frame.depth[:6, :8], segmentation=seg)
    feats = f.features(frame)
    has = np.any(feats.dense() != 0, axis=-1)
    assert np.array_equal(has, seg == 0)
    every = make_featurizer("oracle-open")
    every.reset(label_phrases=PHRASES)
    assert np.array_equal(np.any(every.features(frame).dense() != 0, axis=-1), seg >= 0)
    with pytest.raises(ValueError, match="min_pixels: expected an integer >= 0, got -2"):
        GroundedOracleFeaturizer(min_pixels=-2)


def test_drop_small_segments_counts_pixels_per_segment():
    seg = np.array([[0, 0, 1], [0, 2, 2], [-1, 2, 3]])
    assert np.array_equal(drop_small_segments(seg, 3), [[0, 0, -1], [0, 2, 2], [-1, 2, -1]])
    assert np.array_equal(drop_small_segments(seg, 0), seg)
    assert np.array_equal(drop_small_segments(np.full((2, 2), -1), 5), np.full((2, 2), -1))
    with pytest.raises(ValueError, match="min_pixels: expected an integer >= 0, got True"):
        drop_small_segments(seg, True)


# -- a synthetic map: three objects on a table, rendered with their segmentation ------------------


def _boxes(order):
    """Floor, table and the three objects at fixed places; ``order[k]`` is the object at place k."""
    places = [(-0.3, -0.15, 0.46), (0.3, 0.15, 0.46), (0.0, 0.25, 0.46)]
    colours = [(30, 30, 30), (200, 30, 30), (220, 40, 40)]
    boxes = [Box("floor", (0.0, 0.0, -0.05), (6.0, 6.0, 0.1), (150, 150, 150)),
             Box("table", (0.0, 0.0, 0.375), (1.2, 0.8, 0.05), (120, 75, 40))]
    boxes += [Box(f"object {o}", places[k], (0.12, 0.12, 0.12), colours[o]) for k, o in enumerate(order)]
    return boxes


def _frames(boxes, n=4):
    K = intrinsics_from_fovy(60.0, 96, 72)
    return [render_boxes(boxes, K, pose, 72, 96) for pose in orbit_poses((0.0, 0.0, 0.45), 1.2, 0.7, n)]


def _labels(order):
    """Label phrases of a scene of :func:`_boxes`: segmentation id = box index."""
    out = {0: ["the floor"], 1: ["the table"]}
    out.update({2 + k: PHRASES[o] for k, o in enumerate(order)})
    return out


def _mapped(mapper, order):
    boxes = _boxes(order)
    mapper.reset(object_phrases=_labels(order))
    for frame in _frames(boxes):
        mapper.integrate(frame)
    return boxes


def _inside(point, box, grow=0.03):
    return bool(np.all(point >= box.lo - grow) and np.all(point <= box.hi + grow))


def test_the_mapper_finds_referents_and_says_not_found_for_the_rest():
    f = GroundedOracleFeaturizer()
    mapper = ConceptMapper(f, MapperConfig(min_score=f.score_floor))
    boxes = _mapped(mapper, [0, 1, 2])
    assert mapper.privileged and len(mapper.map) > 1000
    for text, obj in [("the mallet", 1), ("the ceramic mug", 0), ("a tool to drive nails", 1), ("the tool", 1),
                      ("the black mug", 0), ("the red cup", 2), ("the table", None)]:
        res = mapper.locate(text)
        assert res.found, (text, res.reason)
        if obj is not None:
            assert _inside(res.best.median, boxes[2 + obj]), (text, res.best.median)
            assert float(np.median(res.best.scores_n)) == pytest.approx(1.0)
    both = mapper.locate("something to drink from")
    assert both.found and len(both.regions) == 2
    hit = sorted(next(k for k in (0, 2) if _inside(r.median, boxes[2 + k])) for r in both.regions)
    assert hit == [0, 2]
    assert all(float(np.median(r.scores_n)) == pytest.approx(1 / math.sqrt(2)) for r in both.regions)
    for absent in ("the banana", "the red mug", "something to read"):
        res = mapper.locate(absent)
        assert not res.found and res.regions == [] and np.nanmax(res.scores_n) == 0.0, absent


def test_the_text_cache_is_cleared_between_scenes_only_when_texts_depend_on_the_scene():
    f = GroundedOracleFeaturizer()
    mapper = ConceptMapper(f, MapperConfig(min_score=f.score_floor))
    boxes = _mapped(mapper, [0, 1, 2])  # the hammer at place 1 (box 3)
    first = mapper.text_vector("the mallet").copy()
    assert _inside(mapper.locate("the mallet").best.median, boxes[3])
    boxes = _mapped(mapper, [1, 2, 0])  # the same words, another scene: the hammer at place 0 (box 2)
    assert not np.array_equal(mapper.text_vector("the mallet"), first)
    res = mapper.locate("the mallet")
    assert res.found and _inside(res.best.median, boxes[2]) and not _inside(res.best.median, boxes[3])
    # Scene-independent text embeddings keep their cache.
    closed = ConceptMapper(OracleFeaturizer(ColorNameEncoder()))
    closed.reset({0: "red"})
    vec = closed.text_vector("red")
    closed.reset({0: "blue"})
    assert closed.text_vector("red") is vec


def test_privileged_labels_reads_info_only_for_a_privileged_mapper():
    info = {"object_names": ["mug", "hammer"], "object_phrases": [["the mug"], ["the hammer"]]}
    open_mapper = ConceptMapper(GroundedOracleFeaturizer())
    assert privileged_labels(open_mapper, info) == {"object_names": {0: "mug", 1: "hammer"},
                                                    "object_phrases": {0: ["the mug"], 1: ["the hammer"]}}
    assert privileged_labels(open_mapper, None) == {}
    perceived = ConceptMapper(make_featurizer(PerceptionSpec("color")))
    assert not perceived.privileged and privileged_labels(perceived, info) == {}
    open_mapper.reset(**privileged_labels(open_mapper, info))
    assert open_mapper.locate("the hammer").found is False  # an empty map: grounded, but nothing fused


# -- environments and an episode ---------------------------------------------------------------------


def test_env_info_has_object_phrases_aligned_with_object_names():
    import gymnasium as gym

    import sim_envs  # noqa: F401  (registers the environments)
    from sim_envs.scenes.episodes import load_episodes

    eps = load_episodes(V2)
    index = next(i for i, e in enumerate(eps.episodes) if e.goals[0].description_kind == "function")
    env = gym.make("cf/TabletopRearrange-v0", episodes=str(V2), width=32, height=24).unwrapped
    try:
        _, info = env.reset(seed=0, options={"episode_index": index})
        names, phrases = info["object_names"], info["object_phrases"]
        assert len(phrases) == len(names) == len(env.sim.scene.objects) > 1
        for name, obj, mine in zip(names, env.sim.scene.objects, phrases):
            assert mine == sorted(mine) == answer_phrases(obj) and f"the {name}" in mine
        goal = eps.episodes[index].goals[0]
        target = info["object_ids"].index(goal.object_id)
        assert [i for i, p in enumerate(phrases) if goal.description in p] == [target]  # the goal is unique
        _, _, _, _, info2 = env.step(np.array([0, 0, 0, 0, 1], np.float32))
        assert info2["object_phrases"] == phrases
    finally:
        env.close()


def test_map_pusher_with_oracle_open_solves_an_episode_named_by_function():
    from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode
    from sim_envs.scenes.episodes import load_episodes

    eps = load_episodes(V2)
    ep = next(e for e in eps.episodes if e.goals[0].description_kind == "function" and len(e.goals) == 1)
    try:
        rec = run_episode(EpisodeJob("t", "rearrange-v2", "tabletop_rearrange", "map-pusher", {"encoder": "oracle-open"}, ep, 0,
                                     {"width": 128, "height": 96, "scan_frames": 6}))
    finally:
        close_cached_envs()
    assert rec["status"] == "ok", rec.get("error")
    assert rec["encoder"] == "oracle-open" and rec["extras"]["privileged"] is True
    assert rec["metrics"]["success"], (ep.instruction, rec["metrics"])
