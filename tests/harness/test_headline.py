"""The headline figures: computed from sealed-suite records, refused from slices."""

import json

import pytest

from conceptfusion.errors import HarnessError
from harness.report import headline as hl


def _rec(suite, agent, ep, success, enc="embedded-v2", **extras):
    metrics = {"success": success}
    metrics.update(extras.pop("metrics", {}))
    return {"suite": suite, "agent": agent, "encoder": enc, "episode_id": f"e{ep:03d}", "seed": 0, "status": "ok",
            "metrics": metrics, "extras": extras}


def _pair_records(monkeypatch, n=10, map_wins=4, twin_wins=1):
    monkeypatch.setitem(hl.SEALED_SUITES, "search-v2", n)
    recs = []
    for i in range(n):
        both = i >= map_wins + twin_wins + 2  # the last episodes: both succeed
        recs.append(_rec("search-v2", "map-navigator", i, both or i < map_wins, uses_map=True, goal_split="seen" if i % 2 else "held_out_category"))
        recs.append(_rec("search-v2", "twin-navigator", i, both or map_wins <= i < map_wins + twin_wins, twin_of="map-navigator", uses_map=False))
    return recs


def test_headline_pairs_each_map_agent_with_its_twin(monkeypatch):
    figs = hl.headline(_pair_records(monkeypatch))["search-v2"]["embedded-v2"]
    nav, twin = figs["agents"]["map-navigator"]["success"], figs["agents"]["twin-navigator"]["success"]
    assert (nav["successes"], twin["successes"], nav["n"]) == (7, 4, 10)  # 4 map-only, 1 twin-only, 3 both
    d = figs["twins"]["map-navigator - twin-navigator"]
    assert d["diff"] == pytest.approx(0.3) and (d["map_only"], d["twin_only"], d["pairs"]) == (4, 1, 10)
    assert d["p"] == pytest.approx(0.375, abs=1e-3)  # exact McNemar, 4 vs 1
    assert nav["ci"][0] < 0.7 < nav["ci"][1]
    groups = figs["agents"]["map-navigator"]["by_group"]
    assert groups["seen"]["n"] + groups["held_out_category"]["n"] == 10
    table = hl.headline_table({"figures": {"search-v2": {"embedded-v2": figs}}})
    assert "| `search-v2` | embedded-v2 | map-navigator 7/10 | twin-navigator 4/10 | +0.30 [" in table


def test_chain_positions_count_chains_long_enough(monkeypatch):
    monkeypatch.setitem(hl.SEALED_SUITES, "chain-v2", 3)
    recs = [_rec("chain-v2", "map-navigator", 0, False, metrics={"reached_1": True, "reached_2": False}),
            _rec("chain-v2", "map-navigator", 1, True, metrics={"reached_1": True, "reached_2": True, "reached_3": True}),
            _rec("chain-v2", "map-navigator", 2, False, metrics={"reached_1": False, "reached_2": False, "reached_3": False,
                                                                  "reached_4": False})]
    pos = hl.headline(recs)["chain-v2"]["embedded-v2"]["agents"]["map-navigator"]["positions"]
    assert {k: (v["successes"], v["n"]) for k, v in pos.items()} == {"1": (2, 3), "2": (1, 3), "3": (1, 2), "4": (0, 1)}
    table = hl.positions_table({"figures": hl.headline(recs)})
    assert "| `chain-v2` | map-navigator | embedded-v2 | 2/3 = 0.67 | 1/3 = 0.33 | 1/2 = 0.50 | 0/1 = 0.00 |" in table


def test_a_slice_or_a_foreign_suite_is_no_headline(monkeypatch):
    recs = _pair_records(monkeypatch)
    with pytest.raises(HarnessError, match="has 9 records; the headline needs all 10"):
        hl.headline(recs[:-2])
    with pytest.raises(HarnessError, match="record of suite 'search-v2-develop'"):
        hl.headline(recs + [_rec("search-v2-develop", "map-navigator", 0, True)])


def test_the_readme_block_is_replaced_between_its_markers(monkeypatch):
    figs = {"figures": hl.headline(_pair_records(monkeypatch))}
    text = f"intro\n{hl.README_START}\nold table\n{hl.README_END}\nrest\n"
    out = hl.readme_with_tables(text, figs)
    assert out.startswith(f"intro\n{hl.README_START}\n| suite |") and out.endswith(f"{hl.README_END}\nrest\n")
    assert "old table" not in out and hl.headline_table(figs) in out and hl.agents_table(figs) not in out
    with pytest.raises(HarnessError, match="expected the markers"):
        hl.readme_with_tables("no markers", figs)


def test_strip_record_keeps_what_the_figures_need():
    r = {"suite": "s", "agent": "a", "encoder": "e", "episode_id": "x", "seed": 0, "status": "ok", "run_id": "r",
         "metrics": {"success": True, "spl": 0.5, "reached_2": True}, "extras": {"twin_of": "b", "path_xy": [[0, 0]]},
         "timings": {"wall_s": 1.0}}
    assert hl.strip_record(r) == {"suite": "s", "agent": "a", "encoder": "e", "episode_id": "x", "seed": 0, "status": "ok",
                                  "metrics": {"success": True, "reached_2": True}, "extras": {"twin_of": "b"}}


def test_committed_headline_is_recomputed_from_its_records_and_headlines_the_readme():
    records = [json.loads(line) for line in hl.RECORDS_FILE.read_text().splitlines()]
    measured = json.loads(hl.MEASURED_FILE.read_text())
    assert hl.headline(records) == measured["figures"]
    assert measured["sealed_manifest_sha256"] == hl._manifest_sha()
    readme = (hl.DATA_DIR.parents[2] / "README.md").read_text()
    assert hl.headline_table(measured) in readme  # the README's one headline table; the others: docs/results.md
    assert hl.positions_table(measured) not in readme
