"""Results store: round trip, crash safety, format/version checks, resume keys, run settings."""

import json
import math
import warnings

import numpy as np
import pytest

from harness.runner.results import (
    RESULTS_VERSION, EpisodeKey, ResultsFormatError, agent_label, append_record, check_run_config, completed_keys,
    latest_records, load_results, make_record, read_run_config, record_key, repair_results, write_run_config,
)


def _rec(episode_id="ep-0", status="ok", **over):
    fields = dict(run_id="r1", suite="search", task="object_search", agent="map-navigator",
                  agent_kwargs={"integrate_every": 3, "encoder": "test"}, encoder="test", episode_id=episode_id,
                  seed=0, status=status, metrics={"success": True, "spl": 0.5}, timings={"wall_s": 1.5},
                  category="mug", extras={"path_xy": [[0.0, 0.0], [1.0, 1.0]]})
    fields.update(over)
    return make_record(**fields)


def test_agent_label_excludes_encoder_and_sorts():
    assert agent_label("map-navigator", {"integrate_every": 3, "encoder": "x"}) == "map-navigator[integrate_every=3]"
    assert agent_label("a", {"b": 1, "a": "z"}) == "a[a=z,b=1]"
    assert agent_label("random-walker", {}) == "random-walker"


def test_make_record_fills_and_validates():
    r = _rec()
    assert r["format"] == "cf-results" and r["version"] == RESULTS_VERSION
    assert r["harness_version"] and r["finished_at"].endswith("+00:00")
    assert r["error"] is None
    r2 = _rec(metrics={"d": float("nan"), "n": np.int64(4), "ok": np.bool_(True)})
    assert r2["metrics"] == {"d": None, "n": 4, "ok": True}
    with pytest.raises(ValueError, match="status expected one of"):
        _rec(status="crashed")
    with pytest.raises(TypeError, match="seed expected int, got str"):
        _rec(seed="0")
    with pytest.raises(ValueError, match="missing required field"):
        make_record(run_id="r")
    with pytest.raises(ValueError, match="unknown field"):
        _rec(succes=True)
    with pytest.raises(TypeError, match=r"metrics\['x'\]"):
        _rec(metrics={"x": "high"})


def test_round_trip(tmp_path):
    path = tmp_path / "run" / "results.jsonl"
    recs = [_rec(f"ep-{i}", metrics={"success": i % 2 == 0, "spl": i / 10}) for i in range(5)]
    for r in recs:
        append_record(path, r)
    assert load_results(path) == recs
    assert load_results(tmp_path / "missing.jsonl") == []


def test_half_written_tail_is_skipped_and_repaired(tmp_path):
    path = tmp_path / "results.jsonl"
    recs = [_rec(f"ep-{i}") for i in range(3)]
    for r in recs:
        append_record(path, r)
    good = path.read_bytes()
    line = json.dumps(_rec("ep-3")).encode()
    path.write_bytes(good + line[: len(line) // 2])
    with pytest.warns(UserWarning, match=r"results.jsonl: line 4: skipping a half-written"):
        assert load_results(path) == recs
    with pytest.raises(ResultsFormatError, match="repair_results"):
        append_record(path, _rec("ep-3"))
    assert repair_results(path) == len(line) // 2
    assert path.read_bytes() == good
    assert repair_results(path) == 0
    append_record(path, _rec("ep-3"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert [r["episode_id"] for r in load_results(path)] == ["ep-0", "ep-1", "ep-2", "ep-3"]


def test_complete_json_without_newline_counts_as_half_written(tmp_path):
    path = tmp_path / "results.jsonl"
    append_record(path, _rec("ep-0"))
    path.write_bytes(path.read_bytes() + json.dumps(_rec("ep-1")).encode())
    with pytest.warns(UserWarning, match="line 2"):
        assert len(load_results(path)) == 1


def test_corrupt_middle_line(tmp_path):
    path = tmp_path / "results.jsonl"
    lines = [json.dumps(_rec("ep-0")), "{not json", json.dumps(_rec("ep-1"))]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ResultsFormatError, match=r"results.jsonl: line 2: corrupt record"):
        load_results(path, strict=True)
    with pytest.warns(UserWarning, match="line 2: skipping a corrupt record"):
        assert [r["episode_id"] for r in load_results(path)] == ["ep-0", "ep-1"]


def test_newer_version_and_foreign_format_raise(tmp_path):
    path = tmp_path / "results.jsonl"
    newer = dict(_rec(), version=RESULTS_VERSION + 1)
    path.write_text(json.dumps(newer) + "\n")
    with pytest.raises(ResultsFormatError, match=rf"line 1: .*version {RESULTS_VERSION + 1}.*supported version "
                                                 rf"{RESULTS_VERSION}"):
        load_results(path)
    path.write_text(json.dumps({"format": "cf-episodes", "version": 1}) + "\n")
    with pytest.raises(ResultsFormatError, match="format 'cf-episodes', expected 'cf-results'"):
        load_results(path)


def test_resume_keys(tmp_path):
    path = tmp_path / "results.jsonl"
    append_record(path, _rec("ep-0"))
    append_record(path, _rec("ep-1", status="failed", error="boom", metrics={}))
    append_record(path, _rec("ep-2", status="timeout"))
    keys = completed_keys(load_results(path))
    assert EpisodeKey("search", "map-navigator[integrate_every=3]", "test", "ep-1", 0) in keys
    assert len(keys) == 3
    assert {k.episode_id for k in completed_keys(load_results(path), statuses=("ok",))} == {"ep-0"}
    # a retried episode: the newest record wins
    append_record(path, _rec("ep-1", metrics={"success": True}))
    latest = latest_records(load_results(path))
    assert len(latest) == 3
    assert [r["status"] for r in latest if r["episode_id"] == "ep-1"] == ["ok"]
    assert record_key(_rec("ep-0", seed=1)) != record_key(_rec("ep-0"))
    assert record_key(_rec("ep-0", agent_kwargs={"integrate_every": 5})) != record_key(_rec("ep-0"))


def test_run_config(tmp_path):
    config = {"suite": "search", "agents": ["a", "b"], "seeds": (0, 1), "timeout_s": 60.0}
    write_run_config(tmp_path, config)
    stored = read_run_config(tmp_path)
    assert stored["seeds"] == [0, 1] and stored["agents"] == ["a", "b"]
    doc = json.loads((tmp_path / "run.json").read_text())
    assert doc["format"] == "cf-run" and doc["version"] == 1
    check_run_config(tmp_path, config)
    write_run_config(tmp_path, config)  # same settings: fine
    with pytest.raises(ResultsFormatError, match=r"timeout_s: stored 60.0, now 30.0"):
        write_run_config(tmp_path, dict(config, timeout_s=30.0))
    write_run_config(tmp_path, dict(config, timeout_s=30.0), overwrite=True)
    assert math.isclose(read_run_config(tmp_path)["timeout_s"], 30.0)
    with pytest.raises(FileNotFoundError, match="no run settings"):
        read_run_config(tmp_path / "nowhere")
    (tmp_path / "run.json").write_text(json.dumps({"format": "cf-run", "version": 9, "config": {}}))
    with pytest.raises(ResultsFormatError, match="version 9"):
        read_run_config(tmp_path)


def test_check_run_records_refuses_another_runs_record_naming_the_line(tmp_path):
    from harness.runner.results import check_run_records

    path = tmp_path / "results.jsonl"
    check_run_records(path, "r1")  # no file yet: nothing to refuse
    for rec in (_rec("ep-0"), _rec("ep-1"), _rec("ep-2", run_id="r2")):
        append_record(path, rec)
    with pytest.raises(ResultsFormatError, match=rf"^{path}: line 3: expected records of this folder's run 'r1' \(its run.json\), "
                                                 r"got a record of run 'r2'"):
        check_run_records(path, "r1")


def test_check_run_records_refuses_two_outcomes_of_one_episode_and_passes_identical_duplicates(tmp_path):
    from harness.runner.results import check_run_records

    path = tmp_path / "results.jsonl"
    for rec in (_rec("ep-0"), _rec("ep-1"), _rec("ep-0", timings={"wall_s": 9.0})):  # the same outcome, other timings
        append_record(path, rec)
    check_run_records(path, "r1")
    assert len(latest_records(load_results(path))) == 2  # counted once
    append_record(path, _rec("ep-1", status="failed", metrics={"success": False}))
    with pytest.raises(ResultsFormatError, match=rf"^{path}: lines 2 and 4: expected one outcome per episode, got two records of "
                                                 r"search map-navigator\[integrate_every=3\] \[test\] episode ep-1 seed 0 that "
                                                 r"differ \(status ok vs failed"):
        check_run_records(path, "r1")
    other_seed = tmp_path / "seeds.jsonl"  # another seed is another episode key, whatever its outcome
    for rec in (_rec("ep-0"), _rec("ep-0", seed=1, metrics={"success": False})):
        append_record(other_seed, rec)
    check_run_records(other_seed, "r1")


def test_report_loading_warns_about_another_runs_records_and_two_outcomes(tmp_path):
    from harness.runner.results import load_runs

    write_run_config(tmp_path, {"run_id": "r1", "settings": {}})
    path = tmp_path / "results.jsonl"
    for rec in (_rec("ep-0"), _rec("ep-1", run_id="r2"), _rec("ep-0", status="failed", metrics={"success": False})):
        append_record(path, rec)
    with pytest.warns(UserWarning) as caught:
        records = load_runs([tmp_path])
    assert len(records) == 3
    messages = [str(w.message) for w in caught]
    assert messages == [
        f"{path}: line 2: expected records of this folder's run 'r1' (its run.json), got a record of run 'r2'; "
        "the report counts the last record of each episode",
        f"{path}: lines 1 and 3: expected one outcome per episode, got two records of search "
        "map-navigator[integrate_every=3] [test] episode ep-0 seed 0 that differ (status ok vs failed, metrics "
        '{"spl": 0.5, "success": true} vs {"success": false}); the report counts the last record of each episode',
    ]
