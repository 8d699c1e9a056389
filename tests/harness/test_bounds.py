"""Regression bounds: the statistics worked by hand, the committed bounds recomputed from the
committed calibration records, the check's verdicts (missing agent, upper bound, lower bound
borrowed by a user agent), and sabotaged agents that the regression run must refuse."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents.registry import AGENTS
from harness.commands import _check_bounds
from harness.runner import bounds
from harness.runner.results import make_record
from harness.runner.suites import BOUNDS_FILE, HEADLINE_GATE, SUITES, get_suite, suite_episodes
from sim_envs.scenes.episodes import load_episodes

REPO = Path(__file__).resolve().parents[2]


# ------------------------------------------------------------------------------ statistics
def test_lower_and_upper_counts_worked_by_hand():
    # Bin(10, 1.0) never falls short, so any failure breaks the lower bound: c = 10.
    assert bounds.lower_count(1.0, 10) == 10
    # Bin(20, 0.5): P(K <= 5) = 0.0207 <= 0.05 < P(K <= 6) = 0.0577, so fewer than 6 fails.
    assert bounds.lower_count(0.5, 20) == 6
    # Bin(20, 0.0) has no successes: an upper bound of 0, and a lower bound of 0 that cannot fail.
    assert bounds.upper_count(0.0, 20) == 0 and bounds.lower_count(0.0, 20) == 0
    # Bin(20, 0.1): P(K > 4) = 0.0432 <= 0.05 < P(K > 3) = 0.1330, so more than 4 fails.
    assert bounds.upper_count(0.1, 20) == 4


@pytest.mark.parametrize("rate", [0.04, 0.3, 0.5, 0.71, 0.9, 1.0])
@pytest.mark.parametrize("n", [10, 37, 80])
def test_a_lower_bound_fails_exactly_when_the_clopper_pearson_upper_bound_is_below_the_calibrated_rate(rate, n):
    c = bounds.lower_count(rate, n)
    for k in range(n + 1):
        assert (k < c) == (bounds.clopper_pearson(k, n, side="upper") < rate - 1e-12), (k, c)


def test_derive_bound_meets_power_and_false_alarm_targets():
    # 100 of 100: a drop to 0.85 is caught by "any failure fails" once 1 - 0.85^n >= 0.8, n = 10.
    perfect = bounds.derive_bound("a", "lower", 100, 100, 100)
    assert (perfect.episodes, perfect.count, perfect.value) == (10, 10, 1.0)
    assert perfect.detection == pytest.approx(1 - 0.85**10) and perfect.false_alarm == 0.0
    # 0 of 100 (a random agent): a rise to 0.15 is caught by "any success fails" from n = 10 on.
    never = bounds.derive_bound("r", "upper", 0, 100, 100)
    assert (never.episodes, never.count, never.value) == (10, 0, 0.0)
    for k in (45, 71, 90):
        b = bounds.derive_bound("a", "lower", k, 100, 100)
        assert b.power_met and b.can_fail and b.detection >= bounds.POWER
        assert b.false_alarm <= 1 - bounds.CONFIDENCE < b.false_alarm_expected < 0.15
        shorter = bounds.lower_count(k / 100, b.episodes - 1)  # the chosen count is the smallest that works
        assert bounds.detection_probability("lower", shorter, b.episodes - 1, k / 100) < bounds.POWER
    capped = bounds.derive_bound("a", "lower", 50, 100, 30)  # a budget too small: the power reached, not faked
    assert capped.episodes == 30 and not capped.power_met and capped.detection < bounds.POWER
    with pytest.raises(ValueError, match="expected 'lower' or 'upper'"):
        bounds.derive_bound("a", "lid", 1, 2, 3)


# ------------------------------------------------------------------------------ committed bounds
def test_family_confidence_holds_the_whole_gate_to_its_alarm_rate():
    level = bounds.family_confidence(10)
    assert 1.0 - level ** 10 == pytest.approx(bounds.FAMILY_ALARM)
    assert bounds.family_confidence(1) == pytest.approx(1.0 - bounds.FAMILY_ALARM)
    with pytest.raises(ValueError, match="at least 1"):
        bounds.family_confidence(0)


def test_committed_bounds_are_recomputed_from_the_committed_records():
    """The bounds file is what the code derives from the calibration records (not read back)."""
    recomputed = bounds.derive_bounds()
    assert recomputed == json.loads(BOUNDS_FILE.read_text())
    assert bounds.check() == []
    for name, entry in recomputed["suites"].items():
        suite = get_suite(name)
        for agent, b in entry["agents"].items():
            cal = bounds.load_calibration(suite)[agent]
            level = recomputed["method"]["check_confidence"]
            again = bounds.derive_bound(agent, b["bound"], sum(cal), len(cal), entry["settings"]["max_episodes"],
                                        check_confidence=bounds.family_confidence(recomputed["method"]["bounds"]))
            assert again.as_json() == b and round(bounds.family_confidence(recomputed["method"]["bounds"]), 6) == level
            # the counts are set at the family-wise level: never stricter than a per-bound 95% bound
            per_bound = bounds.derive_bound(agent, b["bound"], sum(cal), len(cal), entry["settings"]["max_episodes"])
            assert per_bound.episodes == b["episodes"]
            assert (b["count"] <= per_bound.count) if b["bound"] == "lower" else (b["count"] >= per_bound.count)
            held = suite.lower_bounds if b["bound"] == "lower" else suite.upper_bounds
            assert held[agent] == b["value"] and suite.agent_limits[agent] == b["episodes"]


def test_every_builtin_agent_has_a_bound_that_can_fail_where_the_budget_allows_one():
    bounded, cannot = {}, set()
    for suite in bounds.regression_suites():
        max_n = bounds.derive_suite(suite)["settings"]["max_episodes"]
        cal = bounds.load_calibration(suite)
        for agent in suite.agents:
            kind = "upper" if agent in suite.upper_bounds else "lower"
            value = suite.upper_bounds.get(agent, suite.lower_bounds.get(agent))
            assert value is not None, f"{suite.name}: {agent} has no bound"
            bounded.setdefault(agent, []).append(kind)
            n = suite.agent_limits[agent]
            if (value * n >= 1 - 1e-9) if kind == "lower" else (value < 1.0):
                continue
            # a lower bound of 0: no pinned count the budget allows gives this agent a lower bound that can fail
            rate = sum(cal[agent]) / len(cal[agent])
            assert kind == "lower" and all(bounds.lower_count(rate, m) == 0 for m in range(1, max_n + 1))
            cannot.add((suite.name, agent))
    builtin = {n for n, spec in AGENTS.items()  # not the agents other tests register from plugins
               if (spec.factory if isinstance(spec.factory, str) else spec.factory.__module__).startswith("agents.")}
    # the matched twins are bounded in the headline gate (the v2 suites), beside the agents they twin
    twins = {n for n in builtin if AGENTS[n].twin_of}
    assert twins == {"twin-navigator", "twin-pusher"}
    # the language-planner agents are not gated yet: their tests (tests/agents/test_instruct_planner.py) run them
    ungated = {"generic-planner", "map-planner"}
    assert len(builtin) == 12 and set(bounded) == builtin - ungated
    assert {a for a, kinds in bounded.items() if "upper" in kinds} == set(bounds.UPPER_BOUND_AGENTS)
    assert cannot == {("regression-search", "frame-searcher")}  # the one the bounds module documents
    embedded = get_suite("regression-rearrange-embedded")
    assert embedded.encoder == "embedded" and set(embedded.lower_bounds) == {"map-pusher", "frame-pusher"}


def test_the_headline_gate_is_the_v2_regression_suites_with_the_shipped_pipeline():
    assert {s.name for s in bounds.regression_suites()} >= set(HEADLINE_GATE)
    headline = {"regression-rearrange-v2": "rearrange-v2", "regression-search-v2": "search-v2"}
    assert set(headline) == set(HEADLINE_GATE)
    for name in HEADLINE_GATE:
        suite, shown = get_suite(name), get_suite(headline[name])
        # the headline's perception and cameras, its agents (the weak frame-searcher aside: it cannot get a bound)
        assert suite.encoder == shown.default_encoder == "embedded-v2" and suite.env_kwargs == shown.env_kwargs
        assert set(shown.agents) - set(suite.agents) <= {"frame-searcher"}
        # every agent is bounded, the map agents' twins included
        assert set(suite.agent_limits) == set(suite.agents)
        twins = {a for a in suite.agents if AGENTS[a].twin_of}
        assert twins and all(AGENTS[t].twin_of in suite.agents for t in twins)
        assert all(suite.lower_bounds.get(a, 0) * suite.agent_limits[a] >= 1 for a in suite.lower_bounds), name  # every lower bound can fail


def test_calibration_episodes_are_not_regression_episodes():
    for suite in bounds.regression_suites():
        pinned = load_episodes(suite.episodes_file).episodes
        calibration = load_episodes(suite.calibration_file).episodes
        assert len(calibration) >= 100
        assert not {e.episode_id for e in pinned} & {e.episode_id for e in calibration}
        assert not {e.scene for e in pinned} & {e.scene for e in calibration}  # other tables and apartments too
        assert suite.limit <= len(suite_episodes(suite)) <= len(pinned)


def test_calibration_episodes_regenerate_identically():
    from scenes.make_calibration import build_files
    from scenes.shipped import ROOT

    files = build_files()
    assert len(files) == 2 + 150 + 20
    assert all((ROOT / rel).read_text() == text for rel, text in files.items())


def test_check_reports_a_tampered_bound(tmp_path):
    data = json.loads(BOUNDS_FILE.read_text())
    data["suites"]["regression-rearrange"]["agents"]["map-pusher"]["value"] = 0.1
    tampered = tmp_path / "bounds.json"
    tampered.write_text(json.dumps(data))
    (problem,) = bounds.check(bounds_file=tampered)
    assert "regression-rearrange/agents/map-pusher/value" in problem and "committed 0.1" in problem


# ------------------------------------------------------------------------------ the check
def _records(suite: str, agent: str, successes: list[bool]) -> list[dict]:
    return [make_record(run_id="t", suite=suite, task=get_suite(suite).task, agent=agent, encoder="oracle",
                        episode_id=f"ep-{i:04d}", seed=0, status="ok", metrics={"success": s})
            for i, s in enumerate(successes)]


def _passing(suite: str) -> list[dict]:
    s = get_suite(suite)
    out = []
    for agent, n in s.agent_limits.items():
        k = round(s.lower_bounds[agent] * n) if agent in s.lower_bounds else round(s.upper_bounds[agent] * n)
        out += _records(suite, agent, [True] * k + [False] * (n - k))
    return out


def test_check_passes_at_the_bounds_and_fails_an_agent_without_records(capsys):
    suite = "regression-rearrange"
    records = _passing(suite)
    assert _check_bounds(records, (suite,)) == 0
    dropped = [r for r in records if r["agent"] != "frame-pusher"]
    assert _check_bounds(dropped, (suite,)) == 1
    assert "REGRESSION regression-rearrange: frame-pusher has no records" in capsys.readouterr().err
    # an agent the run did not name is not required; one it named is
    assert _check_bounds(dropped, (suite,), agents=("map-pusher", "random-pusher")) == 0
    assert _check_bounds(dropped, (suite,), agents=("map-pusher", "frame-pusher")) == 1


def test_check_fails_below_a_lower_bound_above_an_upper_bound_and_a_short_run(capsys):
    suite = get_suite("regression-rearrange")
    records = _passing(suite.name)
    n = suite.agent_limits["map-pusher"]
    below = [r for r in records if r["agent"] != "map-pusher"] + _records(suite.name, "map-pusher", [False] * n)
    assert _check_bounds(below, (suite.name,)) == 1
    assert "map-pusher succeeded on 0 of" in capsys.readouterr().err
    m = suite.agent_limits["random-pusher"]
    lucky = [r for r in records if r["agent"] != "random-pusher"] + _records(suite.name, "random-pusher", [True] * m)
    assert _check_bounds(lucky, (suite.name,)) == 1
    assert "above its upper bound" in capsys.readouterr().err
    short = [r for r in records if not (r["agent"] == "map-pusher" and r["episode_id"] != "ep-0000")]
    assert _check_bounds(short, (suite.name,)) == 1
    assert f"ran 1 of the {n} pinned episodes" in capsys.readouterr().err
    assert _check_bounds([r for r in short if r["agent"] == "map-pusher"], (suite.name,), agents=("map-pusher",),
                         limited=True) == 0  # --limit: a note, and the rate still checked (1 of 1)
    assert "note: " in capsys.readouterr().err


def test_a_crash_fails_the_check_even_where_the_lower_bound_cannot_tell(capsys):
    suite = get_suite("regression-search")
    records = _passing(suite.name)
    crashed = next(r for r in records if r["agent"] == "frame-searcher" and not r["metrics"]["success"])
    crashed.update(status="failed", error="RuntimeError: boom")
    assert _check_bounds(records, (suite.name,)) == 1
    assert f"frame-searcher crashed on 1 of {suite.agent_limits['frame-searcher']} episodes" in capsys.readouterr().err


def test_an_uncalibrated_regression_suite_fails_the_check(monkeypatch, capsys):
    import dataclasses

    bare = dataclasses.replace(get_suite("regression-search"), lower_bounds={}, upper_bounds={}, agent_limits={}, limit=None)
    monkeypatch.setitem(SUITES, "regression-search", bare)
    assert _check_bounds([], ("regression-search",)) == 1
    assert "no calibrated bounds" in capsys.readouterr().err


# ------------------------------------------------------------------------------ sabotage
SABOTAGE = '''
import numpy as np

from agents.registry import make_agent


class WrongWayPusher:
    """map-pusher, sabotaged: every push goes the opposite way."""

    def __init__(self, encoder="embedded"):
        self.inner = make_agent("map-pusher", encoder=encoder)
        self.privileged = self.inner.privileged  # with oracle perception it reads ground truth

    def reset(self, seed=None):
        self.inner.reset(seed=seed)

    def act(self, observation, info=None):
        action = np.array(self.inner.act(observation, info), dtype=np.float32)
        action[2] = np.arctan2(-np.sin(action[2]), -np.cos(action[2]))
        return action


class NeverStops:
    """oracle-searcher, sabotaged: drives as before but never says stop."""

    privileged = True
    reads_images = False

    def __init__(self):
        self.inner = make_agent("oracle-searcher")

    def reset(self, seed=None):
        self.inner.reset(seed=seed)

    def act(self, observation, info=None):
        action = np.array(self.inner.act(observation, info), dtype=np.float32)
        action[2] = 0.0
        return action
'''


def _run_cli(tmp_path, *args):
    (tmp_path / "cf_sabotage.py").write_text(SABOTAGE)
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    return subprocess.run([sys.executable, "-m", "harness.cli", "run", *args, "--out", str(tmp_path / "run"), "--no-report"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=900)


@pytest.mark.gate
@pytest.mark.parametrize("suite, agent, builtin", [
    ("regression-rearrange", "cf_sabotage:WrongWayPusher", "map-pusher"),
    ("regression-search", "cf_sabotage:NeverStops", "oracle-searcher"),
])
def test_a_sabotaged_agent_fails_the_regression_run(tmp_path, suite, agent, builtin):
    """The sabotaged agent runs the pinned episodes of the built-in one it copies and is held to
    that agent's calibrated lower bound: the regression command exits 1 and names it."""
    n = get_suite(suite).agent_limits[builtin]
    done = _run_cli(tmp_path, "--suite", suite, "--agent", agent, "--bound-as", f"{agent}={builtin}", "--limit", str(n),
                    "--fail-fast", "--workers", "2", "--record", "none")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "crashed" not in done.stderr  # it runs, it just does worse
    assert f"REGRESSION {suite}: {agent} succeeded on" in done.stderr
    assert "below its lower bound" in done.stderr and f"(that of {builtin})" in done.stderr
    # --fail-fast stopped once the lower bound was out of reach: fewer episodes than pinned, and the
    # verdict recomputed from the records that did run says the lower bound cannot be met
    records = [json.loads(line) for line in (tmp_path / "run" / "results.jsonl").read_text().splitlines()]
    k, ran = sum(r["metrics"]["success"] for r in records), len(records)
    assert "--fail-fast: stopped after" in done.stderr and ran < n
    assert k + (n - ran) < get_suite(suite).lower_bounds[builtin] * n


def test_bound_as_needs_an_agent_of_the_run_and_a_builtin(tmp_path):
    done = _run_cli(tmp_path, "--suite", "regression-rearrange", "--agent", "random-pusher",
                    "--bound-as", "cf_sabotage:WrongWayPusher=map-pusher")
    assert done.returncode == 2 and "--bound-as cf_sabotage:WrongWayPusher=map-pusher: " in done.stderr
    assert "is not an --agent of this run" in done.stderr
    done = _run_cli(tmp_path, "--suite", "regression-rearrange", "--agent", "cf_sabotage:WrongWayPusher",
                    "--floor-as", "cf_sabotage:WrongWayPusher=map-pushr")  # the old name, still read
    assert done.returncode == 2 and "map-pusher" in done.stderr


def test_floor_as_is_the_old_name_of_bound_as():
    from harness.cli import build_parser

    args = build_parser().parse_args(["run", "--floor-as", "a=map-pusher", "--bound-as", "b=frame-pusher"])
    assert args.bound_as == ["a=map-pusher", "b=frame-pusher"] and not hasattr(args, "floor_as")


def test_the_docs_show_the_bounds_recomputed_from_the_records():
    # recomputed here from the committed calibration records, not read back from the bounds file
    table = bounds.markdown_table(bounds.derive_bounds())
    page = REPO / "docs" / "regression-gate.md"
    assert table in page.read_text(), f"{page.name}'s bounds table is stale: print bounds.markdown_table(...)"
