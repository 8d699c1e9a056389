"""Agent development runs: calibration episodes only, resumable, summarised per agent."""

import json

import pytest

from conceptfusion.errors import HarnessError
from harness.runner.develop import DEVELOPMENT_EPISODES, develop, development_suite, main, parse_env_options
from harness.runner.suites import SUITES, suite_episodes
from sim_envs.scenes.splits import splits


@pytest.mark.parametrize("name,which", [(n, w) for n in sorted(DEVELOPMENT_EPISODES) for w in DEVELOPMENT_EPISODES[n]])
def test_development_episodes_are_calibration_or_validation_seeds_and_no_suite_runs_them(name, which):
    suite = development_suite(name, episodes=which)
    episodes = suite_episodes(suite)
    role = {"calibration": "calibration", "validation": "tower_val", "dev2": "evaluation"}[which]
    assert episodes and {splits().seed_role(e.scene_seed) for e in episodes} == {role}
    assert suite.env_kwargs == SUITES[name].env_kwargs and suite.agents == SUITES[name].agents
    scenes = {e.scene for e in episodes}
    for other in SUITES.values():
        if other.kind == "episodes":
            assert not scenes & {e.scene for e in suite_episodes(other)}, other.name


def test_unknown_development_suite_is_refused_naming_the_known_ones():
    with pytest.raises(HarnessError, match="search-v2"):
        development_suite("rearrange")  # v1: none
    with pytest.raises(HarnessError, match="--episodes: expected one of calibration, validation, dev2 for search-v2, got 'test'"):
        development_suite("search-v2", episodes="test")


def test_develop_runs_resumes_and_summarises(tmp_path, capsys):
    out = tmp_path / "dev"
    summary = develop("search-v2", out, agents=("random-walker",), limit=2, backend="serial", progress=False)
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 2 and all(r["suite"] == "search-v2-develop" for r in records)
    assert summary == {"random-walker": (sum(bool(r["metrics"]["success"]) for r in records), 2)}
    # a second call with the same settings finds every record and runs nothing
    assert develop("search-v2", out, agents=("random-walker",), limit=2, backend="serial", progress=False) == summary
    assert len((out / "results.jsonl").read_text().splitlines()) == 2
    assert main(["--suite", "nope", "--out", str(out)]) == 2
    assert "expected a suite with development episodes" in capsys.readouterr().err


def test_environment_settings_replace_the_suites_and_name_the_records(tmp_path):
    suite = development_suite("search-v2", parse_env_options(["width=32", "height=24"]))
    assert suite.env_kwargs == {**SUITES["search-v2"].env_kwargs, "width": 32, "height": 24}
    assert suite.name == "search-v2-develop@height=24,width=32"
    out = tmp_path / "dev"
    develop("search-v2", out, agents=("random-walker",), limit=1, backend="serial", progress=False)
    develop("search-v2", out, agents=("random-walker",), limit=1, backend="serial", progress=False,
            env_kwargs={"width": 32, "height": 24})
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    # the second settings ran their own episode instead of resuming the first's record
    assert [r["suite"] for r in records] == ["search-v2-develop", "search-v2-develop@height=24,width=32"]


def test_unknown_or_malformed_environment_settings_are_refused(capsys):
    with pytest.raises(HarnessError, match="focal_length.*expected one of.*width"):
        development_suite("search-v2", {"focal_length": 3})
    with pytest.raises(ValueError, match="expected KEY=VALUE, got 'width'"):
        parse_env_options(["width"])
    assert parse_env_options(["scan_frames=4", "segmentation=false", "name=abc"]) == {
        "scan_frames": 4, "segmentation": False, "name": "abc"}
    assert main(["--suite", "rearrange-v2", "--env-option", "wheels=3", "--out", "unused"]) == 2
    assert "not a setting of the tabletop_rearrange environment" in capsys.readouterr().err
