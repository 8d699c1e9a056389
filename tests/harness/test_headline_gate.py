"""The gate on the headline pipeline: the v2 regression suites (``embedded-v2`` pinned, the agents'
shipped settings, 320x240 cameras) meet their calibrated bounds, their committed calibration
records come back exactly, and three sabotaged pipelines each fail the gate: a broken
``identify``, a broken presume rule and degraded mask proposals.

These tests run hundreds of embedded-perception episodes (about ten minutes on two cores). They
are marked ``gate`` like the v1 gate and ``headline_gate`` of their own: the README's test command
leaves the gates out (``-m "not gate and not install"`` in ``pyproject.toml``), CI runs them with
``python -m pytest -q -m "gate or install"``, and ``-m headline_gate`` runs these alone."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from harness.commands import _check_bounds
from harness.runner.bounds import replay_sample
from harness.runner.run import RunConfig, run_suites
from harness.runner.suites import HEADLINE_GATE as HEADLINE_SUITES, get_suite

REPO = Path(__file__).resolve().parents[2]

pytestmark = [pytest.mark.gate, pytest.mark.headline_gate]


def test_the_headline_regression_suites_meet_their_bounds(tmp_path):
    """Every agent of the v2 suites runs its pinned episodes with the shipped settings and none
    falls below its calibrated lower bound or rises above its upper bound."""
    records = run_suites(RunConfig(suites=HEADLINE_SUITES, backend="process", workers=2, record="none"), tmp_path,
                         progress=False)
    assert len(records) == sum(sum(get_suite(s).agent_limits.values()) for s in HEADLINE_SUITES)
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records if r["status"] != "ok"]
    # every agent that perceives ran the shipped tower (the random and privileged ones take no encoder)
    perceiving = [r for r in records if "encoder" in r["agent_kwargs"]]
    assert {r["agent"] for r in perceiving} == {"map-pusher", "twin-pusher", "frame-pusher", "map-navigator", "twin-navigator"}
    assert {r["encoder"] for r in perceiving} == {"embedded-v2"}
    assert _check_bounds(records, HEADLINE_SUITES) == 0


@pytest.mark.parametrize("suite", HEADLINE_SUITES)
def test_a_sample_of_headline_calibration_episodes_comes_back_exactly(suite):
    assert replay_sample(get_suite(suite), per_agent=2) == []


# ------------------------------------------------------------------------------ sabotage
SABOTAGE = '''
import dataclasses

from agents.registry import make_agent


def backwards_identify(encoder="embedded-v2"):
    """map-pusher whose identify ranks the table's objects backwards: a named object the score
    floor rejects becomes the thing on the table least like its name."""
    agent = make_agent("map-pusher", encoder=encoder)
    mapper, right = agent.mapper, agent.mapper.identify

    def identify(text, candidates):
        res = right(text, candidates)
        return dataclasses.replace(res, regions=res.regions[::-1],
                                   extras={**res.extras, "margins": res.extras["margins"][::-1]})

    mapper.identify = identify
    return agent


def eager_presume(encoder="embedded-v2"):
    """map-navigator whose presume rule fires from the first step instead of step 200: it heads
    for its best guess before it has looked around."""
    return make_agent("map-navigator", encoder=encoder, presume_after=1)


def coarse_proposals(encoder="embedded-v2"):
    """map-pusher whose mask proposals keep only regions of at least 2% of the frame (0.1%
    shipped): small objects merge into the table or vanish."""
    return make_agent("map-pusher", encoder=encoder, proposer="rgbd:min_area_fraction=0.02")
'''


def _run_cli(tmp_path, *args):
    (tmp_path / "cf_headline_sabotage.py").write_text(SABOTAGE)
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    return subprocess.run([sys.executable, "-m", "harness.cli", "run", *args, "--out", str(tmp_path / "run"), "--no-report"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=1800)


@pytest.mark.parametrize("suite, sabotage, builtin", [
    ("regression-rearrange-v2", "backwards_identify", "map-pusher"),
    ("regression-search-v2", "eager_presume", "map-navigator"),
    ("regression-rearrange-v2", "coarse_proposals", "map-pusher"),
])
def test_a_sabotaged_headline_pipeline_fails_the_gate(tmp_path, suite, sabotage, builtin):
    """The sabotaged agent runs the pinned episodes of the built-in one it breaks, held to that
    agent's calibrated lower bound: the regression command exits 1 and names it."""
    agent = f"cf_headline_sabotage:{sabotage}"
    n = get_suite(suite).agent_limits[builtin]
    done = _run_cli(tmp_path, "--suite", suite, "--agent", agent, "--bound-as", f"{agent}={builtin}", "--limit", str(n),
                    "--fail-fast", "--workers", "2", "--record", "none")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "crashed" not in done.stderr  # it runs, it just does worse
    assert f"REGRESSION {suite}: {agent} succeeded on" in done.stderr and f"(that of {builtin})" in done.stderr
    records = [json.loads(line) for line in (tmp_path / "run" / "results.jsonl").read_text().splitlines()]
    assert all(r["encoder"] == "embedded-v2" for r in records)
    k, ran = sum(r["metrics"]["success"] for r in records), len(records)
    assert k + (n - ran) < get_suite(suite).lower_bounds[builtin] * n  # the lower bound is out of reach on what ran
