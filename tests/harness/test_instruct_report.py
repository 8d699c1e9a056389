"""The instruct-v2 table: map-planner against generic-planner on the same instruction episodes."""

import math

import pytest

from conceptfusion.errors import HarnessError
from harness.report import instruct
from harness.report.markdown import build_report


def _rec(agent, ep, ok, kind, enc="oracle-open", privileged=True, planner_s=None, context_s=0.0):
    extras = {"privileged": privileged, "instruction_kind": kind}
    if planner_s is not None:
        extras["planner"] = {"backend": "offline", "calls": 3, "planner_s": planner_s, "context_s": context_s}
    return {"format": "cf-results", "version": 1, "run_id": "r", "suite": "instruct-v2", "task": "object_search",
            "agent": agent, "encoder": enc, "episode_id": ep, "seed": 0, "status": "ok", "agent_kwargs": {}, "error": None,
            "metrics": {"success": ok, "spl": 0.5 if ok else 0.0}, "timings": {"agent_s": 8.0, "env_s": 2.0}, "extras": extras}


def _records():
    kinds = ["need", "room", "relation"] * 4
    mp = [True] * 10 + [False] * 2            # 10 of 12
    gp = [True] * 5 + [False] * 6 + [True]    # 6 of 12: 5 lost, 1 gained by the map planner
    recs = [_rec("map-planner", f"e{i}", v, kinds[i], planner_s=0.5, context_s=2.0) for i, v in enumerate(mp)]
    recs += [_rec("generic-planner", f"e{i}", v, kinds[i], planner_s=0.1) for i, v in enumerate(gp)]
    recs += [_rec("oracle-searcher", f"e{i}", True, kinds[i], enc="none") for i in range(12)]
    return recs


def test_rows_pair_the_planners_on_the_same_episodes():
    rows = instruct.instruct_rows(_records())
    assert [(r.encoder, r.agent) for r in rows] == [("oracle-open", "map-planner"), ("oracle-open", "generic-planner"),
                                                   ("none", "oracle-searcher")]
    mp = rows[0]
    assert (mp.n, mp.successes) == (12, 10) and mp.by_kind == {"need": (4, 4), "room": (3, 4), "relation": (3, 4)}
    diff, lo, hi, p, n = mp.diff
    assert n == 12 and math.isclose(diff, 4 / 12) and lo < diff < hi
    assert math.isclose(p, 2 * sum(math.comb(6, k) for k in range(2)) / 2**6)  # 5 gained, 1 lost
    assert math.isclose(mp.planner_share, 12 * 0.5 / (12 * 10.0)) and math.isclose(mp.listing_share, 12 * 2.0 / 120.0)
    assert rows[1].diff is None and rows[2].planner_share is None
    table = instruct.instruct_table(rows)
    assert "| oracle-open (privileged) | map-planner | 10/12 = 0.83" in table and "+0.33 [" in table
    assert "| none | oracle-searcher (privileged) | 12/12" in table and "5.0% / 20.0%" in table


def test_no_instruction_records_is_an_error_and_the_readme_needs_its_markers():
    with pytest.raises(HarnessError, match="instruct-v2"):
        instruct.instruct_rows([dict(r, suite="search-v2") for r in _records()])
    with pytest.raises(HarnessError, match="markers"):
        instruct.readme_with_table("no markers", "| t |")


def test_kept_records_hold_what_the_table_needs():
    kept = [instruct.keep_record(r) for r in _records()]
    assert instruct.instruct_table(instruct.instruct_rows(kept)) == instruct.instruct_table(instruct.instruct_rows(_records()))
    assert "kept_calls" not in str(kept)


def test_the_report_has_the_section(tmp_path):
    doc = build_report(_records(), tmp_path)
    (table,) = [b for b in doc.blocks if getattr(b, "name", "") == "instruct"]
    assert table.rows[0][2] == "map-planner (privileged)" and table.rows[0][3].text == "10/12"


def test_the_readme_table_is_recomputed_from_the_kept_records():
    if not instruct.RECORDS_FILE.is_file():
        pytest.fail(f"{instruct.RECORDS_FILE} is missing: cfharness develop instruct RUN... --write keeps it")
    table = instruct.instruct_table(instruct.instruct_rows(instruct.read_kept_records(instruct.RECORDS_FILE)))
    readme = (instruct.RECORDS_FILE.parents[3] / "README.md").read_text()
    assert f"{instruct.README_START}\n{table}\n{instruct.README_END}" in readme
