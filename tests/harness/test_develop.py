"""Agent development runs: calibration episodes only, resumable, summarised per agent."""

import json

import pytest

from conceptfusion.errors import HarnessError
from harness.runner.develop import DEVELOPMENT_EPISODES, develop, development_suite, main
from harness.runner.suites import SUITES, suite_episodes
from sim_envs.scenes.splits import splits


@pytest.mark.parametrize("name", sorted(DEVELOPMENT_EPISODES))
def test_development_episodes_are_calibration_seeds_and_no_suite_runs_them(name):
    suite = development_suite(name)
    episodes = suite_episodes(suite)
    assert episodes and {splits().seed_role(e.scene_seed) for e in episodes} == {"calibration"}
    assert suite.env_kwargs == SUITES[name].env_kwargs and suite.agents == SUITES[name].agents
    scenes = {e.scene for e in episodes}
    for other in SUITES.values():
        if other.kind == "episodes":
            assert not scenes & {e.scene for e in suite_episodes(other)}, other.name


def test_unknown_development_suite_is_refused_naming_the_known_ones():
    with pytest.raises(HarnessError, match="search-v2"):
        development_suite("rearrange")  # v1: none


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
