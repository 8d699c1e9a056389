"""The search gate's PyBullet slice (``regression-search-v2-pybullet``): the gate's pinned
apartment searches run in PyBullet, ``oracle-open`` perception pinned, held to a bound calibrated
on the gate's calibration searches in PyBullet.

It gates the simulator (geometry, physics, depth, segmentation, the agents' control); the
privileged ``oracle-open`` perception keeps the MuJoCo-trained tower's domain gap out of it (the
sim-to-sim table measures that gap). It bounds ``map-navigator`` alone: every bound is set at the
gate's family-wise level, and a second bound in the family would lower ``map-pusher``'s lower bound
in ``regression-rearrange-v2`` to a count the backwards-``identify`` sabotage reaches
(test_headline_gate.py). The gate test is marked ``gate``: left out of the README's
test command, run by ``python -m pytest -q -m "gate or install"`` (``.ci/run``)."""

from __future__ import annotations

import pytest

from harness.commands import _check_bounds
from harness.runner.bounds import MAX_EPISODES, regression_suites
from harness.runner.run import RunConfig, run_suites
from harness.runner.suites import HEADLINE_GATE, get_suite

SLICE = "regression-search-v2-pybullet"


def test_the_pybullet_slice_is_the_search_gate_in_pybullet_with_oracle_open_perception():
    pyb, base = get_suite(SLICE), get_suite("regression-search-v2")
    assert pyb in regression_suites() and SLICE not in HEADLINE_GATE  # gated, but not the headline pipeline
    # the same pinned and calibration searches and cameras, in PyBullet
    assert (pyb.episodes_file, pyb.calibration_file) == (base.episodes_file, base.calibration_file)
    assert pyb.env_kwargs == {**base.env_kwargs, "backend": "pybullet"}
    assert pyb.encoder == "oracle-open" and MAX_EPISODES[SLICE] == MAX_EPISODES[base.name]
    # the map agent alone (one bound: the family-wise level leaves every other bound of the gate as it was)
    assert pyb.agents == ("map-navigator",) and "map-navigator" in base.agents
    # calibrated: a lower bound that can fail
    assert set(pyb.agent_limits) == set(pyb.lower_bounds) == set(pyb.agents) and not pyb.upper_bounds
    assert all(pyb.lower_bounds[a] * pyb.agent_limits[a] >= 1 for a in pyb.agents)


@pytest.mark.gate
def test_the_pybullet_slice_meets_its_bounds(tmp_path):
    """The slice's agent runs its pinned searches in PyBullet, oracle-open perception, and does
    not fall below its calibrated lower bound."""
    suite = get_suite(SLICE)
    records = run_suites(RunConfig(suites=(SLICE,), backend="process", workers=2, record="none"), tmp_path, progress=False)
    assert len(records) == sum(suite.agent_limits.values())
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records if r["status"] != "ok"]
    assert {r["extras"]["sim"] for r in records} == {"pybullet"}
    perceiving = [r for r in records if "encoder" in r["agent_kwargs"]]
    assert {r["agent"] for r in perceiving} == {"map-navigator"}
    assert {r["encoder"] for r in perceiving} == {"oracle-open"}
    for r in records:
        assert isinstance(r["metrics"]["success"], bool) and r["metrics"]["steps"] >= 1
        assert 0.0 <= r["metrics"]["spl"] <= 1.0 and r["metrics"]["distance_to_goal"] >= 0.0
    assert _check_bounds(records, (SLICE,)) == 0
