"""The sim-to-sim table: a suite's records beside its PyBullet variant's, paired by episode."""

import math

import pytest

from conceptfusion.errors import HarnessError
from harness.report import sim_to_sim as s2s
from harness.report.markdown import build_report


def _rec(suite, agent, ep, ok, enc="oracle-open", privileged=True, seed=0):
    return {"format": "cf-results", "version": 1, "run_id": "r", "suite": suite, "task": "object_search", "agent": agent,
            "encoder": enc, "episode_id": ep, "seed": seed, "status": "ok", "agent_kwargs": {}, "error": None,
            "metrics": {"success": ok}, "timings": {"wall_s": 1.0}, "extras": {"privileged": privileged}}


def _records():
    mj = [True] * 8 + [False] * 4            # episodes 0-11 in MuJoCo: 8 of 12
    pb = [True] * 6 + [False, False] + [True, False, False, False]  # PyBullet: 7 of 12; 2 lost, 1 gained
    recs = [_rec("search-v2", "map-navigator", f"e{i}", v) for i, v in enumerate(mj)]
    recs += [_rec("search-v2-pybullet", "map-navigator", f"e{i}", v) for i, v in enumerate(pb)]
    recs.append(_rec("search-v2", "map-navigator", "only-mujoco", True))  # not paired: left out
    recs.append(_rec("search-v2", "twin-navigator", "e0", True))          # no PyBullet twin: no row
    return recs


def test_pairs_count_the_same_episodes_in_both_simulators():
    (pair,) = s2s.sim_to_sim(_records())
    assert (pair.suite, pair.agent, pair.encoder, pair.privileged) == ("search-v2", "map-navigator", "oracle-open", True)
    assert (pair.n, pair.mujoco, pair.pybullet) == (12, 8, 7)
    assert math.isclose(pair.diff, -1 / 12)
    assert math.isclose(pair.p, 1.0)  # 1 gained, 2 lost: exact McNemar 2 * P(X <= 1 | n=3) = 1
    assert pair.ci[0] < pair.diff < pair.ci[1]
    table = s2s.sim_to_sim_table([pair])
    assert "| `search-v2` | map-navigator | oracle-open (privileged) | 8/12 = 0.67" in table and "7/12 = 0.58" in table
    assert "-0.08 [" in table


def test_no_suite_in_both_simulators_is_an_error_and_the_readme_needs_its_markers():
    with pytest.raises(HarnessError, match="-pybullet"):
        s2s.sim_to_sim([r for r in _records() if not r["suite"].endswith("-pybullet")])
    with pytest.raises(HarnessError, match="markers"):
        s2s.readme_with_table("no markers", "| t |")
    text = f"a\n{s2s.README_START}\nold\n{s2s.README_END}\nb\n"
    assert s2s.readme_with_table(text, "| t |") == f"a\n{s2s.README_START}\n| t |\n{s2s.README_END}\nb\n"


def test_the_report_has_the_section_when_a_suite_ran_in_both(tmp_path):
    doc = build_report(_records(), tmp_path)
    tables = [b for b in doc.blocks if getattr(b, "name", "") == "sim-to-sim"]
    assert len(tables) == 1 and tables[0].rows[0][3].text == "8/12" and tables[0].rows[0][4].text == "7/12"
def test_the_readme_table_is_recomputed_from_the_kept_records():
    if not s2s.RECORDS_FILE.is_file():
        pytest.fail(f"{s2s.RECORDS_FILE} is missing: cfharness develop sim-to-sim RUN... --write keeps it")
    table = s2s.sim_to_sim_table(s2s.sim_to_sim(s2s.read_kept_records(s2s.RECORDS_FILE)))
    readme = (s2s.RECORDS_FILE.parents[3] / "README.md").read_text()
    assert f"{s2s.README_START}\n{table}\n{s2s.README_END}" in readme
