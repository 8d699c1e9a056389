"""The open-vocabulary query suite (``query-open``): its queries, split groups, scoring and jobs."""

from __future__ import annotations

import numpy as np
import pytest

from harness.maps.query_open import (
    QUERY_KINDS, SPLIT_GROUPS, load_open_scene, object_group, open_queries, open_scene_ids, pooled_table,
    run_open_query_scene, score_open_query_scene,
)
from harness.maps.query_open_develop import CALIBRATION_DIR, answer_at, floor_table
from sim_envs.scenes.format import load_scene
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.run import RunConfig
from sim_envs.assets.library import instance_of_asset
from sim_envs.scenes.descriptions import describable
from sim_envs.scenes.splits import splits


def test_scenes_are_evaluation_seeds_only():
    ids = open_scene_ids(None)
    assert len(ids) == 24 and len(open_scene_ids(160)) == 160
    for sid in open_scene_ids(160):
        assert splits().seed_role(load_open_scene(sid).seed) == "evaluation", sid
    with pytest.raises(ValueError, match="v2 tabletop id"):
        load_open_scene("tabletop-0111")


def test_queries_are_deterministic_unique_and_point_at_their_referents():
    kinds_seen, groups_seen = set(), set()
    for sid in open_scene_ids(12):
        scene = load_open_scene(sid)
        qs = open_queries(scene, seed=0)
        assert qs == open_queries(scene, seed=0)
        texts = [q["text"] for q in qs]
        assert len(texts) == len(set(texts)), "a phrase is asked once per scene"
        by_id = {o.id: o for o in scene.objects}
        for q in qs:
            assert q["kind"] in QUERY_KINDS and q["group"] in SPLIT_GROUPS
            kinds_seen.add(q["kind"])
            groups_seen.add(q["group"])
            answered = [o for o in scene.objects if q["text"] in describable(o).answers_to()]
            if q["kind"] == "absent":
                assert q["objects"] == [] and answered == [], q
            else:
                assert sorted(q["objects"]) == sorted(o.id for o in answered), q
                assert all(i in by_id for i in q["objects"])
        assert sum(q["kind"] == "absent" for q in qs) == 3
    assert kinds_seen == set(QUERY_KINDS)
    assert {"seen", "held_out_instance", "held_out_category"} <= groups_seen


def test_split_groups_follow_the_split_file():
    sp = splits()
    for sid in open_scene_ids(24):
        for obj in load_open_scene(sid).objects:
            inst = instance_of_asset(obj.asset)
            group = object_group(obj)
            if sp.categories[inst.category] == "test":
                assert group == "held_out_category"
            elif group == "seen":
                assert sp.instances[inst.id] == "train" and sp.categories[inst.category] == "train"
            elif group == "held_out_instance":
                assert sp.instances[inst.id] == "test" and sp.categories[inst.category] == "train"


def test_oracle_scene_scores_and_pooled_table_recomputes_them():
    sid = open_scene_ids(1)[0]
    metrics, extras, _ = run_open_query_scene(sid, "oracle", frames=6, width=96, height=72)
    queries = extras["queries"]
    present = [q for q in queries if q["kind"] != "absent"]
    assert metrics["n_queries"] == len(present) > 0 and metrics["n_absent"] == 3
    assert extras["privileged"] is True
    for q in present:
        assert 0.0 <= q["iou"] <= 1.0 and (q["found"] or q["iou"] == 0.0)
    # The oracle labels points with each object's name ("black domino"): asked that way, it is found.
    colour = [q for q in present if q["kind"] == "colour"]
    assert colour and metrics["colour_miou"] > 0.5
    assert metrics["absent_fp_rate"] == 0.0
    rec = {"suite": "query-open", "status": "ok", "encoder": "oracle", "metrics": metrics, "extras": extras}
    table = pooled_table([rec, {**rec, "status": "failed"}, {**rec, "suite": "query"}])
    for kind in ("name", "colour"):
        entries = [q for q in present if q["kind"] == kind]
        row = table[("oracle", kind, "all")]
        assert row["n"] == len(entries)
        assert row["miou"] == pytest.approx(np.mean([q["iou"] for q in entries]))
        assert row["miou"] == pytest.approx(metrics[f"{kind}_miou"])
    assert table[("oracle", "absent", "all")] == {"fp_rate": 0.0, "n": 3}
    assert table[("oracle", "all", "all")]["n"] == len(present)


def test_unfloored_regions_give_the_floored_answers_of_any_floor():
    """The calibration-table tool (``query_open_develop``) replays every floor from one unfloored
    pass: its answer at the encoder's floor is the suite's floored answer, query by query."""
    scene = load_scene(sorted(CALIBRATION_DIR.glob("tabletop-v2-*.json"))[0])
    kw = dict(frames=5, width=96, height=72)
    _, floored, _ = score_open_query_scene(scene, "embedded-v2", **kw)
    _, loose, _ = score_open_query_scene(scene, "embedded-v2", floor=False, all_regions=True, **kw)
    from agents.builtin import make_mapper

    floor = make_mapper("embedded-v2", "rgbd").config.min_score
    assert floor is not None
    pairs = list(zip(floored["queries"], loose["queries"]))
    assert pairs and all(a["text"] == b["text"] for a, b in pairs)
    for a, b in pairs:
        found, iou_ = answer_at(b, floor)
        assert found == a["found"], a["text"]
        if a["kind"] != "absent":
            assert iou_ == pytest.approx(a["iou"], abs=1e-4), a["text"]
            assert answer_at(b, None) == (b["found"], pytest.approx(b["iou"], abs=1e-4))
    # without a floor at least as much is found
    assert sum(b["found"] for _, b in pairs) >= sum(a["found"] for a, _ in pairs)
    table = floor_table(loose["queries"], floor)
    present = [a for a, _ in pairs if a["kind"] != "absent"]
    assert table["all"]["n"] == len(present)
    assert table["all"]["miou"] == pytest.approx(np.mean([a["iou"] for a in present]), abs=1e-4)
    assert table["absent_found"] == pytest.approx(np.mean([a["found"] for a, _ in pairs if a["kind"] == "absent"]))


def test_answer_at_takes_the_first_region_reaching_the_floor():
    entry = {"kind": "name", "regions": [[0.30, 0.1], [0.40, 0.8], [0.50, 0.6]]}
    assert answer_at(entry, None) == (True, 0.1)
    assert answer_at(entry, 0.35) == (True, 0.8)
    assert answer_at(entry, 0.45) == (True, 0.6)
    assert answer_at(entry, 0.6) == (False, 0.0)
    assert answer_at({"kind": "absent", "regions": [[0.4]]}, 0.3) == (True, 0.0)
    assert answer_at({"kind": "name", "found": False}, None) == (False, 0.0)


def test_suite_jobs_default_to_the_v2_tower_and_keep_an_explicit_encoder():
    jobs = map_suite_jobs("query-open", RunConfig(suites=("query-open",), limit=2), "r")
    assert [j.encoder for j in jobs] == ["embedded-v2"] * 2
    assert [j.scene_id for j in jobs] == open_scene_ids(2)
    jobs = map_suite_jobs("query-open", RunConfig(suites=("query-open",), limit=1, encoder="oracle"), "r")
    assert [j.encoder for j in jobs] == ["oracle"]
    # v1 suites keep the v1 tower by default
    assert {j.encoder for j in map_suite_jobs("query", RunConfig(suites=("query",), limit=1), "r")} == {"embedded"}


def test_v2_episode_suites_default_to_the_v2_tower_and_record_how_the_goal_is_named(tmp_path):
    from harness.runner.run import episode_jobs, run_suites
    from harness.runner.suites import get_suite

    jobs = episode_jobs(get_suite("search-v2"), RunConfig(suites=("search-v2",), agents=("map-navigator",), limit=1), "r")
    assert jobs[0].agent_kwargs["encoder"] == "embedded-v2"
    jobs = episode_jobs(get_suite("search"), RunConfig(suites=("search",), agents=("map-navigator",), limit=1), "r")
    assert jobs[0].agent_kwargs["encoder"] == "embedded"
    config = RunConfig(suites=("rearrange-v2",), agents=("random-pusher",), limit=2, backend="serial", record="none")
    records = run_suites(config, tmp_path / "run", progress=False)
    assert [r["status"] for r in records] == ["ok", "ok"]
    kinds = [r["extras"]["description_kind"] for r in records]
    assert kinds == [j.episode.goals[0].description_kind for j in episode_jobs(get_suite("rearrange-v2"), config, "r")]
    assert all(k in ("name", "synonym", "attribute", "function", "parent") for k in kinds)
    # how seen each goal object is, recomputed from the scene files and the split file
    from sim_envs.scenes.episodes import SCENES_ROOT
    from sim_envs.scenes.format import load_scene
    from sim_envs.scenes.splits import object_group

    jobs = episode_jobs(get_suite("rearrange-v2"), config, "r")
    expected = [object_group(load_scene(SCENES_ROOT / j.episode.scene).object(j.episode.goals[0].object_id)) for j in jobs]
    assert [r["extras"]["goal_split"] for r in records] == expected


def test_v1_episodes_record_no_goal_split(tmp_path):
    from harness.runner.run import run_suites

    config = RunConfig(suites=("rearrange",), agents=("random-pusher",), limit=1, backend="serial", record="none")
    (record,) = run_suites(config, tmp_path / "run", progress=False)
    assert record["status"] == "ok" and "goal_split" not in record["extras"]


def test_report_gives_success_by_description_kind_and_goal_split(tmp_path):
    from harness.report.document import render_markdown
    from harness.report.markdown import build_report

    def rec(i, kind, split, ok):
        return {"suite": "rearrange-v2", "task": "tabletop_rearrange", "agent": "map-pusher", "agent_kwargs": {},
                "encoder": "embedded-v2", "episode_id": f"e{i}", "seed": 0, "status": "ok", "error": None,
                "metrics": {"success": ok}, "timings": {"wall_s": 1.0}, "category": "mug",
                "extras": {"description_kind": kind, "goal_split": split}}

    records = [rec(0, "name", "seen", True), rec(1, "name", "held_out_category", False),
               rec(2, "function", "seen", True), rec(3, "synonym", "validation", False), rec(4, "name", "seen", False)]
    md = render_markdown(build_report(records, tmp_path))
    assert "Success by how the goal was named" in md
    assert "| map-pusher | embedded-v2 | 1.00 (1) | 0.33 (3) | 0.00 (1) |" in md
    # split groups in the split file's order (seen first), not alphabetically
    assert "Success by how seen the goal object is" in md
    assert "| agent | encoder | seen | held_out_category | validation |" in md
    assert "| map-pusher | embedded-v2 | 0.67 (3) | 0.00 (1) | 0.00 (1) |" in md


def test_answers_without_the_table_rim_overlap_their_objects_better():
    """``drop_support`` (the default) against whole regions on the first calibration table, a
    small scan: the present queries' answers overlap their objects better on average, and the
    switch reaches the mapper (some answers differ)."""
    scene = load_scene(sorted(CALIBRATION_DIR.glob("tabletop-v2-*.json"))[0])
    kw = dict(frames=6, width=160, height=120)
    _, trimmed, _ = score_open_query_scene(scene, "embedded-v2", **kw)
    _, whole, _ = score_open_query_scene(scene, "embedded-v2", drop_support=False, **kw)
    pairs = [(a, b) for a, b in zip(trimmed["queries"], whole["queries"]) if a["kind"] != "absent"]
    assert pairs and all(a["text"] == b["text"] for a, b in pairs)
    better = sum(a["iou"] > b["iou"] for a, b in pairs)
    worse = sum(a["iou"] < b["iou"] for a, b in pairs)
    assert better > worse
    assert np.mean([a["iou"] for a, _ in pairs]) > np.mean([b["iou"] for _, b in pairs])
