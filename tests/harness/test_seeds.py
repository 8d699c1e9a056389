"""Several seeds per episode (``--seeds``): the jobs, the stored settings (a run.json of before
resumes), the between-seed spread worked by hand, and its table in the report."""

from __future__ import annotations

import json

import pytest

from harness.report.markdown import write_report
from harness.report.stats import seed_spread, within_noise
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.results import make_record, record_key
from harness.runner.run import RunConfig, episode_jobs, run_suites
from harness.runner.suites import get_suite


def test_each_episode_runs_with_consecutive_seeds():
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=2, seed=5, seeds=3)
    jobs = episode_jobs(get_suite("regression-rearrange"), config, "r")
    assert [(j.episode.episode_id[-4:], j.seed) for j in jobs] == [
        ("0000", 5), ("0000", 6), ("0000", 7), ("0001", 5), ("0001", 6), ("0001", 7)]
    assert len({record_key(j.key_record()) for j in jobs}) == 6
    maps = map_suite_jobs("spatial", RunConfig(suites=("spatial",), limit=1, seeds=2), "r")
    assert sorted({j.seed for j in maps}) == [0, 1] and len(maps) == 2 * len({(j.agent, j.scene_id) for j in maps})


def test_seeds_are_stored_only_when_more_than_one_so_older_runs_resume(tmp_path):
    one = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial")
    assert "seeds" not in one.settings()
    assert RunConfig(suites=("regression-rearrange",), seeds=2).settings()["seeds"] == 2
    run_suites(one, tmp_path, progress=False)
    stored = json.loads((tmp_path / "run.json").read_text())
    assert "seeds" not in json.dumps(stored)  # what a run.json written before --seeds holds
    assert len(run_suites(one, tmp_path, resume=True, progress=False)) == 1
    with pytest.raises(ValueError, match="--resume expects the settings"):
        run_suites(RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, seeds=2,
                             backend="serial"), tmp_path, resume=True, progress=False)


def _recs(agent: str, per_seed: dict[int, list[bool]]) -> list[dict]:
    return [make_record(run_id="t", suite="s", task="tabletop_rearrange", agent=agent, encoder="oracle",
                        episode_id=f"e{i}", seed=seed, status="ok", metrics={"success": v})
            for seed, values in per_seed.items() for i, v in enumerate(values)]


def test_seed_spread_and_noise_worked_by_hand(tmp_path):
    a = _recs("a", {0: [True, True], 1: [True, False], 2: [False, False]})  # rates 1, 0.5, 0
    b = _recs("b", {0: [True, False], 1: [False, True], 2: [True, False]})  # 0.5 each
    c = _recs("c", {0: [True, True], 1: [True, True], 2: [True, True]})  # 1 each
    only_two = _recs("d", {0: [True, True], 1: [True], 2: [False, True]})  # e1 lacks seed 1: counts e0 only
    sa, sb, sc, sd = seed_spread(a + b + c + only_two)
    assert sa.rates == (1.0, 0.5, 0.0) and sa.mean == 0.5 and sa.std == pytest.approx(0.5)
    assert (sa.low, sa.high, sa.episodes, sa.seeds) == (0.0, 1.0, 2, (0, 1, 2))
    assert sb.rates == (0.5, 0.5, 0.5) and sb.std == 0.0
    assert sd.episodes == 1 and sd.rates == (1.0, 1.0, 0.0)
    assert within_noise(sa, sb) is True  # 0 apart, spread 0.5
    assert within_noise(sb, sc) is False  # 0.5 apart, no spread
    assert within_noise(sa, sc) is True  # 0.5 apart, combined spread 0.5
    (single,) = seed_spread(_recs("e", {0: [True, False]}))
    assert single.std != single.std and within_noise(single, sa) is None  # NaN: one seed has no spread

    text = write_report(a + b + c, tmp_path / "report").read_text()
    section = text[text.index("### Seed noise"):]
    assert "| a | oracle | 3 | 2 | 0.500 | 0.500 | 0.000 - 1.000 |" in section
    assert "| b (oracle) | c (oracle) | -0.500 | 0.000 | no |" in section
    assert "| a (oracle) | b (oracle) | +0.000 | 0.500 | within noise |" in section
    assert "### Seed noise" not in write_report(_recs("e", {0: [True]}), tmp_path / "one").read_text()
