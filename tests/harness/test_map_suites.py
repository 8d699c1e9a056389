"""Map suites: jobs, records, and the figures that must hold with privileged (oracle) features."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.maps.ablation import segmentation_scores
from harness.maps.query import iou
from harness.maps.scan import load_shipped_scene, point_labels
from harness.runner.backends import run_jobs
from harness.runner.map_jobs import MapJob, map_suite_jobs, run_map_job
from harness.runner.results import record_key
from harness.runner.run import RunConfig

TABLETOP = "tabletop-0111"


def _job(suite, agent, encoder, scene, tmp_path=None, **options):
    return MapJob(run_id="t", suite=suite, agent=agent, encoder=encoder, scene_id=scene, options=options,
                  out_dir=None if tmp_path is None else str(tmp_path))


def test_iou_and_segmentation_scores_by_hand():
    assert iou(np.array([1, 1, 0, 0], bool), np.array([0, 1, 1, 0], bool)) == pytest.approx(1 / 3)
    assert iou(np.zeros(3, bool), np.zeros(3, bool)) == 0.0
    # classes 0 (3 points) and 1 (1 point); one class-0 point predicted 1, one not predicted
    s = segmentation_scores(np.array([0, 1, -1, 1]), np.array([0, 0, 0, 1]), 2)
    assert s["macc"] == pytest.approx((1 / 3 + 1) / 2)
    assert s["fmiou"] == pytest.approx(0.75 * (1 / 3) + 0.25 * (1 / 2))
    with pytest.raises(ValueError, match=r"expected true labels in \[0, 2\)"):
        segmentation_scores(np.array([0]), np.array([2]), 2)


def test_point_labels_prefer_the_smaller_box_and_skip_the_support_surface():
    boxes = np.array([[[0, 0, 0], [1, 1, 1]], [[0.2, 0.2, 0.2], [0.4, 0.4, 0.4]]], float)
    pts = np.array([[0.5, 0.5, 0.5], [0.3, 0.3, 0.3], [0.5, 0.5, 0.001], [2, 2, 2]])
    assert point_labels(pts, boxes).tolist() == [0, 1, -1, -1]


def test_query_record_is_well_formed_and_writes_a_heatmap(tmp_path):
    job = _job("query", "conceptfusion", "color", TABLETOP, tmp_path, frames=6, width=96, height=72)
    (rec,) = run_map_job(job)
    assert rec["status"] == "ok", rec["error"]
    assert (rec["task"], rec["agent"], rec["episode_id"], rec["encoder"]) == ("map_query", "conceptfusion", TABLETOP, "color")
    assert record_key(rec) == record_key(job.key_record())
    for m in ("text", "image", "click"):
        assert 0.0 <= rec["metrics"][f"{m}_miou"] <= 1.0
        assert rec["metrics"][f"{m}_acc25"] <= rec["metrics"][f"{m}_acc15"]
    assert rec["metrics"]["n_objects"] + rec["metrics"]["n_skipped"] == len(load_shipped_scene(TABLETOP).objects)
    heat = np.load(tmp_path / rec["extras"]["heatmap_npz"])
    assert heat["points"].shape == (rec["metrics"]["map_points"], 3) and heat["values"].shape == (rec["metrics"]["map_points"],)


def test_oracle_text_queries_find_the_objects():
    (rec,) = run_map_job(_job("query", "conceptfusion", "oracle", TABLETOP, frames=8, width=128, height=96))
    m = rec["metrics"]
    assert rec["status"] == "ok", rec["error"]
    assert m["text_miou"] > 0.5 and m["text_acc25"] > 0.7
    assert m["click_miou"] > 0.5
    assert m["image_miou"] is None  # the oracle has no image tower
    assert m["absent_fp_rate"] == 0.0


def test_ablation_full_beats_global_with_ground_truth_masks():
    opts = {"frames": 6, "width": 96, "height": 72, "proposer": "gt"}
    recs = {v: run_map_job(_job("ablation", v, "color", TABLETOP, **opts))[0] for v in ("global", "full")}
    assert all(r["status"] == "ok" for r in recs.values())
    assert recs["full"]["metrics"]["macc"] > recs["global"]["metrics"]["macc"]
    assert recs["full"]["task"] == "map_ablation" and recs["full"]["extras"]["privileged"] is True


def test_jobs_per_suite_and_bad_names():
    # "search" runs map-navigator, which takes integrate_every: an option the map suites do not read
    cfg = RunConfig(suites=("query", "search"), encoder="color", limit=2, agent_kwargs={"frames": 6, "integrate_every": 3})
    q = map_suite_jobs("query", cfg, "r")
    # the first two shipped tabletops that are not reserved (tabletop-0111 calibrated the v1 floor)
    assert [j.scene_id for j in q] == ["tabletop-0129", "tabletop-0182"] and q[0].options == {"frames": 6}
    assert len(map_suite_jobs("ablation", cfg, "r")) == 2 * 4
    spatial = map_suite_jobs("spatial", cfg, "r")
    assert len(spatial) == (2 + 2) * 2 and {j.agent for j in spatial} == {"map-3d", "frame-2.5d"}
    assert len({record_key(j.key_record()) for j in spatial}) == len(spatial)
    with pytest.raises(ValueError, match=r"unknown map suite 'querry'; did you mean 'query'"):
        map_suite_jobs("querry", cfg, "r")


def test_a_broken_job_becomes_a_failed_record():
    (rec,) = run_map_job(_job("query", "conceptfusion", "color", "tabletop-9999"))
    assert rec["status"] == "failed" and "no shipped scene 'tabletop-9999'" in rec["error"]


def _outcome(rec: dict) -> tuple:
    """A record without what depends on where or when it ran."""
    return tuple(json.dumps(rec[k], sort_keys=True) for k in ("suite", "task", "agent", "agent_kwargs", "encoder", "episode_id",
                                                               "seed", "status", "metrics", "extras", "category"))


def test_map_jobs_on_the_process_backend_give_the_serial_records_and_heatmaps(tmp_path):
    cfg = RunConfig(suites=("query",), encoder="color", limit=1, agent_kwargs={"frames": 4, "width": 64, "height": 48})
    jobs = map_suite_jobs("query", cfg, "r", out_dir=tmp_path / "serial") + map_suite_jobs("spatial", cfg, "r")[:2]
    pool_jobs = map_suite_jobs("query", cfg, "r", out_dir=tmp_path / "pool") + map_suite_jobs("spatial", cfg, "r")[:2]
    assert pool_jobs[0].out_dir == str((tmp_path / "pool").resolve())  # absolute: any worker writes to the run folder
    serial = sorted(map(_outcome, run_jobs(jobs, backend="serial")))
    pool = sorted(map(_outcome, run_jobs(pool_jobs, backend="process", workers=2)))
    assert pool == serial and len(pool) == 3
    assert all(json.loads(o[7]) == "ok" for o in pool)
    name = json.loads(next(o for o in pool if json.loads(o[0]) == "query")[9])["heatmap_npz"]
    assert (tmp_path / "serial" / name).exists() and (tmp_path / "pool" / name).exists()


def test_a_map_job_past_its_timeout_is_recorded_and_the_run_goes_on():
    cfg = RunConfig(suites=("query",), encoder="color", limit=1, agent_kwargs={"frames": 4, "width": 64, "height": 48})
    (job,) = map_suite_jobs("query", cfg, "r")
    assert job.timeout_s == 600.0  # the suite's per-job limit
    slow = MapJob(**{**job.__dict__, "timeout_s": 0.01})
    (rec,) = run_jobs([slow], backend="process", workers=1)
    assert rec["status"] == "timeout" and "exceeded" in rec["error"] and record_key(rec) == record_key(job.key_record())
    assert rec["task"] == "map_query"


def test_scene_kinds_of_both_worlds():
    from harness.maps.scan import scene_kind, shipped_scene_ids

    assert scene_kind("tabletop-0111") == "tabletop" and scene_kind("household-v2-300000") == "household-v2"
    assert scene_kind("tabletop-v2-300005") == "tabletop-v2"
    for bad in ("tabletop", "kitchen-0001", "tabletop-v3-1", "tabletop-v2-x"):
        with pytest.raises(ValueError, match="expected '<kind>-<number>'"):
            scene_kind(bad)
    v1, v2 = shipped_scene_ids("tabletop"), shipped_scene_ids("tabletop-v2")
    assert v1 and v2 and not set(v1) & set(v2) and all(s.startswith("tabletop-v2-") for s in v2)
    assert load_shipped_scene(v2[0]).table is not None


def test_v2_map_suites_take_the_v2_scenes_and_its_tower():
    from harness.maps.suites import DEFAULT_SCENES, ablation_encoder, scene_ids

    cfg = RunConfig(suites=("query-v2", "ablation-v2", "spatial-v2"), limit=2)
    q = map_suite_jobs("query-v2", cfg, "r")
    assert [j.scene_id for j in q] == scene_ids("tabletop-v2", 2) and {j.encoder for j in q} == {"embedded-v2"}
    spatial = {j.scene_id for j in map_suite_jobs("spatial-v2", cfg, "r")}
    assert spatial == set(scene_ids("household-v2", 2) + scene_ids("tabletop-v2", 2))
    assert len(scene_ids("tabletop-v2", None)) == DEFAULT_SCENES["tabletop-v2"]
    assert ablation_encoder("oracle-open", "v2")[0] == "embedded-v2" and ablation_encoder("oracle")[0] == "embedded"


def test_v2_query_and_ablation_records_with_privileged_features():
    scene = "tabletop-v2-300005"
    opts = {"frames": 8, "width": 128, "height": 96}
    (rec,) = run_map_job(_job("query-v2", "conceptfusion", "oracle", scene, **opts))
    assert rec["status"] == "ok", rec["error"]
    m = rec["metrics"]
    assert m["n_objects"] + m["n_skipped"] == len(load_shipped_scene(scene).objects)
    assert m["text_miou"] > 0.5 and m["absent_fp_rate"] == 0.0 and m["image_miou"] is None
    # the absent names come from other v2 tables, so they are library names, none on this table
    present = {o.name for o in load_shipped_scene(scene).objects}
    assert rec["extras"]["absent"] and not {a["name"] for a in rec["extras"]["absent"]} & present
    gt = {v: run_map_job(_job("ablation-v2", v, "color", scene, proposer="gt", **opts))[0] for v in ("global", "full")}
    assert all(r["status"] == "ok" for r in gt.values())
    assert gt["full"]["metrics"]["macc"] > gt["global"]["metrics"]["macc"]
    assert set(gt["full"]["extras"]["per_class_acc"]) >= {"table"}
