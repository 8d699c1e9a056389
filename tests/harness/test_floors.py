"""Regression floors: the statistics worked by hand, the committed floors recomputed from the
committed calibration records, the check's verdicts (missing agent, ceiling, floor borrowed by a
user agent), and sabotaged agents that the regression run must refuse."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents.registry import AGENTS
from harness.commands import _check_floors
from harness.runner import floors
from harness.runner.results import make_record
from harness.runner.suites import FLOORS_FILE, HEADLINE_GATE, SUITES, get_suite, suite_episodes
from sim_envs.scenes.episodes import load_episodes

REPO = Path(__file__).resolve().parents[2]


# ------------------------------------------------------------------------------ statistics
def test_floor_count_worked_by_hand():
    # Bin(10, 1.0) never falls short, so any failure breaks the floor: c = 10.
    assert floors.floor_count(1.0, 10) == 10
    # Bin(20, 0.5): P(K <= 5) = 0.0207 <= 0.05 < P(K <= 6) = 0.0577, so fewer than 6 fails.
    assert floors.floor_count(0.5, 20) == 6
    # Bin(20, 0.0) has no successes: a ceiling of 0, and a floor of 0 that cannot fail.
    assert floors.ceiling_count(0.0, 20) == 0 and floors.floor_count(0.0, 20) == 0
    # Bin(20, 0.1): P(K > 4) = 0.0432 <= 0.05 < P(K > 3) = 0.1330, so more than 4 fails.
    assert floors.ceiling_count(0.1, 20) == 4


@pytest.mark.parametrize("rate", [0.04, 0.3, 0.5, 0.71, 0.9, 1.0])
@pytest.mark.parametrize("n", [10, 37, 80])
def test_floor_fails_exactly_when_the_clopper_pearson_upper_bound_is_below_the_calibrated_rate(rate, n):
    c = floors.floor_count(rate, n)
    for k in range(n + 1):
        assert (k < c) == (floors.clopper_pearson(k, n, side="upper") < rate - 1e-12), (k, c)


def test_derive_bound_meets_power_and_false_alarm_targets():
    # 100 of 100: a drop to 0.85 is caught by "any failure fails" once 1 - 0.85^n >= 0.8, n = 10.
    perfect = floors.derive_bound("a", "floor", 100, 100, 100)
    assert (perfect.episodes, perfect.count, perfect.value) == (10, 10, 1.0)
    assert perfect.detection == pytest.approx(1 - 0.85**10) and perfect.false_alarm == 0.0
    # 0 of 100 (a random agent): a rise to 0.15 is caught by "any success fails" from n = 10 on.
    never = floors.derive_bound("r", "ceiling", 0, 100, 100)
    assert (never.episodes, never.count, never.value) == (10, 0, 0.0)
    for k in (45, 71, 90):
        b = floors.derive_bound("a", "floor", k, 100, 100)
        assert b.power_met and b.can_fail and b.detection >= floors.POWER
        assert b.false_alarm <= 1 - floors.CONFIDENCE < b.false_alarm_expected < 0.15
        shorter = floors.floor_count(k / 100, b.episodes - 1)  # the chosen count is the smallest that works
        assert floors.detection_probability("floor", shorter, b.episodes - 1, k / 100) < floors.POWER
    capped = floors.derive_bound("a", "floor", 50, 100, 30)  # a budget too small: the power reached, not faked
    assert capped.episodes == 30 and not capped.power_met and capped.detection < floors.POWER
    with pytest.raises(ValueError, match="expected 'floor' or 'ceiling'"):
        floors.derive_bound("a", "lid", 1, 2, 3)


# ------------------------------------------------------------------------------ committed floors
def test_family_confidence_holds_the_whole_gate_to_its_alarm_rate():
    level = floors.family_confidence(10)
    assert 1.0 - level ** 10 == pytest.approx(floors.FAMILY_ALARM)
    assert floors.family_confidence(1) == pytest.approx(1.0 - floors.FAMILY_ALARM)
    with pytest.raises(ValueError, match="at least 1"):
        floors.family_confidence(0)


def test_committed_floors_are_recomputed_from_the_committed_records():
    """The floors file is what the code derives from the calibration records (not read back)."""
    recomputed = floors.derive_floors()
    assert recomputed == json.loads(FLOORS_FILE.read_text())
    assert floors.check() == []
    for name, entry in recomputed["suites"].items():
        suite = get_suite(name)
        for agent, b in entry["agents"].items():
            cal = floors.load_calibration(suite)[agent]
            level = recomputed["method"]["check_confidence"]
            again = floors.derive_bound(agent, b["bound"], sum(cal), len(cal), entry["settings"]["max_episodes"],
                                        check_confidence=floors.family_confidence(recomputed["method"]["bounds"]))
            assert again.as_json() == b and round(floors.family_confidence(recomputed["method"]["bounds"]), 6) == level
            # the counts are set at the family-wise level: never stricter than a per-bound 95% bound
            per_bound = floors.derive_bound(agent, b["bound"], sum(cal), len(cal), entry["settings"]["max_episodes"])
            assert per_bound.episodes == b["episodes"]
            assert (b["count"] <= per_bound.count) if b["bound"] == "floor" else (b["count"] >= per_bound.count)
            held = suite.floors if b["bound"] == "floor" else suite.ceilings
            assert held[agent] == b["value"] and suite.agent_limits[agent] == b["episodes"]


def test_every_builtin_agent_has_a_bound_that_can_fail_where_the_budget_allows_one():
    bounded, cannot = {}, set()
    for suite in floors.regression_suites():
        max_n = floors.derive_suite(suite)["settings"]["max_episodes"]
        cal = floors.load_calibration(suite)
        for agent in suite.agents:
            kind = "ceiling" if agent in suite.ceilings else "floor"
            value = suite.ceilings.get(agent, suite.floors.get(agent))
            assert value is not None, f"{suite.name}: {agent} has no bound"
            bounded.setdefault(agent, []).append(kind)
            n = suite.agent_limits[agent]
            if (value * n >= 1 - 1e-9) if kind == "floor" else (value < 1.0):
                continue
            # a floor of 0: no pinned count the budget allows gives this agent a floor that can fail
            rate = sum(cal[agent]) / len(cal[agent])
            assert kind == "floor" and all(floors.floor_count(rate, m) == 0 for m in range(1, max_n + 1))
            cannot.add((suite.name, agent))
    builtin = {n for n, spec in AGENTS.items()  # not the agents other tests register from plugins
               if (spec.factory if isinstance(spec.factory, str) else spec.factory.__module__).startswith("agents.")}
    # the matched twins are bounded in the headline gate (the v2 suites), beside the agents they twin
    twins = {n for n in builtin if AGENTS[n].twin_of}
    assert twins == {"twin-navigator", "twin-pusher"}
    assert len(builtin) == 10 and set(bounded) == builtin
    assert {a for a, kinds in bounded.items() if "ceiling" in kinds} == set(floors.CEILING_AGENTS)
    assert cannot == {("regression-search", "frame-searcher")}  # the one the floors module documents
    embedded = get_suite("regression-rearrange-embedded")
    assert embedded.encoder == "embedded" and set(embedded.floors) == {"map-pusher", "frame-pusher"}


def test_the_headline_gate_is_the_v2_regression_suites_with_the_shipped_pipeline():
    assert {s.name for s in floors.regression_suites()} >= set(HEADLINE_GATE)
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
        assert all(suite.floors.get(a, 0) * suite.agent_limits[a] >= 1 for a in suite.floors), name  # every floor can fail


def test_calibration_episodes_are_not_regression_episodes():
    for suite in floors.regression_suites():
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


def test_check_reports_a_tampered_floor(tmp_path):
    data = json.loads(FLOORS_FILE.read_text())
    data["suites"]["regression-rearrange"]["agents"]["map-pusher"]["value"] = 0.1
    tampered = tmp_path / "floors.json"
    tampered.write_text(json.dumps(data))
    (problem,) = floors.check(floors_file=tampered)
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
        k = round(s.floors[agent] * n) if agent in s.floors else round(s.ceilings[agent] * n)
        out += _records(suite, agent, [True] * k + [False] * (n - k))
    return out


def test_check_passes_at_the_bounds_and_fails_an_agent_without_records(capsys):
    suite = "regression-rearrange"
    records = _passing(suite)
    assert _check_floors(records, (suite,)) == 0
    dropped = [r for r in records if r["agent"] != "frame-pusher"]
    assert _check_floors(dropped, (suite,)) == 1
    assert "REGRESSION regression-rearrange: frame-pusher has no records" in capsys.readouterr().err
    # an agent the run did not name is not required; one it named is
    assert _check_floors(dropped, (suite,), agents=("map-pusher", "random-pusher")) == 0
    assert _check_floors(dropped, (suite,), agents=("map-pusher", "frame-pusher")) == 1


def test_check_fails_below_a_floor_above_a_ceiling_and_a_short_run(capsys):
    suite = get_suite("regression-rearrange")
    records = _passing(suite.name)
    n = suite.agent_limits["map-pusher"]
    below = [r for r in records if r["agent"] != "map-pusher"] + _records(suite.name, "map-pusher", [False] * n)
    assert _check_floors(below, (suite.name,)) == 1
    assert "map-pusher succeeded on 0 of" in capsys.readouterr().err
    m = suite.agent_limits["random-pusher"]
    lucky = [r for r in records if r["agent"] != "random-pusher"] + _records(suite.name, "random-pusher", [True] * m)
    assert _check_floors(lucky, (suite.name,)) == 1
    assert "above its ceiling" in capsys.readouterr().err
    short = [r for r in records if not (r["agent"] == "map-pusher" and r["episode_id"] != "ep-0000")]
    assert _check_floors(short, (suite.name,)) == 1
    assert f"ran 1 of the {n} pinned episodes" in capsys.readouterr().err
    assert _check_floors([r for r in short if r["agent"] == "map-pusher"], (suite.name,), agents=("map-pusher",),
                         limited=True) == 0  # --limit: a note, and the rate still checked (1 of 1)
    assert "note: " in capsys.readouterr().err


def test_a_crash_fails_the_check_even_where_the_floor_cannot_tell(capsys):
    suite = get_suite("regression-search")
    records = _passing(suite.name)
    crashed = next(r for r in records if r["agent"] == "frame-searcher" and not r["metrics"]["success"])
    crashed.update(status="failed", error="RuntimeError: boom")
    assert _check_floors(records, (suite.name,)) == 1
    assert f"frame-searcher crashed on 1 of {suite.agent_limits['frame-searcher']} episodes" in capsys.readouterr().err


def test_an_uncalibrated_regression_suite_fails_the_check(monkeypatch, capsys):
    import dataclasses

    bare = dataclasses.replace(get_suite("regression-search"), floors={}, ceilings={}, agent_limits={}, limit=None)
    monkeypatch.setitem(SUITES, "regression-search", bare)
    assert _check_floors([], ("regression-search",)) == 1
    assert "no calibrated floors" in capsys.readouterr().err


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
    that agent's calibrated floor: the regression command exits 1 and names it."""
    n = get_suite(suite).agent_limits[builtin]
    done = _run_cli(tmp_path, "--suite", suite, "--agent", agent, "--floor-as", f"{agent}={builtin}", "--limit", str(n),
                    "--fail-fast", "--workers", "2", "--record", "none")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "crashed" not in done.stderr  # it runs, it just does worse
    assert f"REGRESSION {suite}: {agent} succeeded on" in done.stderr
    assert "below its floor" in done.stderr and f"(that of {builtin})" in done.stderr
    # --fail-fast stopped once the floor was out of reach: fewer episodes than pinned, and the
    # verdict recomputed from the records that did run says the floor cannot be met
    records = [json.loads(line) for line in (tmp_path / "run" / "results.jsonl").read_text().splitlines()]
    k, ran = sum(r["metrics"]["success"] for r in records), len(records)
    assert "--fail-fast: stopped after" in done.stderr and ran < n
    assert k + (n - ran) < get_suite(suite).floors[builtin] * n


def test_floor_as_needs_an_agent_of_the_run_and_a_builtin(tmp_path):
    done = _run_cli(tmp_path, "--suite", "regression-rearrange", "--agent", "random-pusher",
                    "--floor-as", "cf_sabotage:WrongWayPusher=map-pusher")
    assert done.returncode == 2 and "is not an --agent of this run" in done.stderr
    done = _run_cli(tmp_path, "--suite", "regression-rearrange", "--agent", "cf_sabotage:WrongWayPusher",
                    "--floor-as", "cf_sabotage:WrongWayPusher=map-pushr")
    assert done.returncode == 2 and "map-pusher" in done.stderr


def test_the_docs_show_the_floors_recomputed_from_the_records():
    # recomputed here from the committed calibration records, not read back from the floors file
    table = floors.markdown_table(floors.derive_floors())
    page = REPO / "docs" / "regression-gate.md"
    assert table in page.read_text(), f"{page.name}'s floors table is stale: print floors.markdown_table(...)"
