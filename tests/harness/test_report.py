"""Report: renders from synthetic records and run folders, links PNGs that exist, skips what it cannot draw."""

import re
from pathlib import Path

import numpy as np
import pytest

from harness.report.markdown import write_report
from harness.runner.results import append_record, make_record
from sim_envs.scenes.episodes import SCENES_ROOT
from sim_envs.scenes.floorplan import occupancy_grid
from sim_envs.scenes.format import load_scene

SCENE = "household/household-0000.json"


def _free_path(n=12):
    """A path over free cells of the shipped scene: the first free cells of the grid's middle row."""
    grid = occupancy_grid(load_scene(SCENES_ROOT / SCENE))
    x, y = grid.centres()
    row = grid.blocked_hw.shape[0] // 2
    free = np.flatnonzero(~grid.blocked_hw[row])[:n]
    return [[float(x[row, j]), float(y[row, j])] for j in free]


def _records(rng):
    path = _free_path()
    recs = []
    cats = ["mug", "bowl", "box"]
    for i in range(30):
        ep = f"search-v1-{i:04d}"
        common = dict(run_id="r1", suite="search", task="object_search", episode_id=ep, seed=0,
                      category=cats[i % 3], timings={"wall_s": 2.0})
        win = bool(rng.random() < 0.85)
        extras = {"uses_map": True, "scene": SCENE, "path_xy": path, "start_xy": path[0], "goal_xy": path[-1]}
        recs.append(make_record(agent="map-navigator", agent_kwargs={"integrate_every": 3}, encoder="test",
                                status="ok", metrics={"success": win, "spl": 0.7 if win else 0.0, "steps": 40 + i},
                                extras=extras, **common))
        lose = bool(rng.random() < 0.2)
        recs.append(make_record(agent="random-walker", encoder="none", status="ok" if i != 5 else "failed",
                                error=None if i != 5 else "RuntimeError: boom",
                                metrics={"success": lose, "spl": 0.3 if lose else 0.0} if i != 5 else {},
                                extras={"uses_map": False}, **common))
    return recs


def _links(text):
    return re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)


def test_report_from_records(tmp_path):
    recs = _records(np.random.default_rng(0))
    heat = tmp_path / "heat.npz"
    pts = np.random.default_rng(1).uniform(-1, 1, (200, 3))
    np.savez(heat, points=pts, values=pts[:, 0])
    recs.append(make_record(run_id="r1", suite="mapping", task="query", agent="mapper", encoder="test",
                            episode_id="scan-0", seed=0, status="ok", metrics={"miou": 0.4, "acc_015": True},
                            extras={"heatmap_npz": "heat.npz", "query": "red mug"}))
    recs.append(make_record(run_id="r1", suite="mapping", task="query", agent="mapper", encoder="test",
                            episode_id="scan-1", seed=0, status="ok", metrics={"miou": 0.5},
                            extras={"heatmap_npz": "missing.npz"}))
    out = tmp_path / "report"
    path = write_report(recs, out, title="Test report", base_dir=tmp_path)
    text = path.read_text()
    assert path == out / "report.md"
    assert text.startswith("# Test report")
    assert "- episodes: 62 (failed 1, ok 61)" in text
    assert "## Suite `search`" in text and "## Suite `mapping`" in text
    assert "| agent | encoder | n | failed/timeout | success | SPL | path: steps | s/episode |" in text
    # a suite's table has the columns its records have: no success, SPL, failures or wall time for the map suite
    assert "| agent | encoder | n | mIoU | 015: accuracy |" in text
    assert re.search(r"\| map-navigator\[integrate_every=3\] \| test \| 30 \| 0/0 \| 0\.\d\d \[0\.\d\d, 0\.\d\d\]", text)
    assert "| random-walker | none | 30 | 1/0 |" in text
    # map-equipped vs map-free, success and SPL
    comp = re.search(r"\| map-navigator\[integrate_every=3\] \(test\) \| random-walker \(none\) \| success \| 30 \|"
                     r" [\d.]+ \| [\d.]+ \| \+([\d.]+) \[\+([\d.]+), ", text)
    assert comp and float(comp.group(2)) > 0
    assert "| spl | 30 |" in text
    assert "map-equipped vs map-free" in text
    links = _links(text)
    assert any(n.startswith("success_search") for n in links)
    assert any(n.startswith("category_search") for n in links)
    assert any(n.startswith("paths_search_map-navigator") for n in links)
    assert any(n.startswith("heatmap_mapping_scan-0") for n in links)
    for name in links:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    # what could not be drawn is named
    assert "## Skipped" in text and "missing.npz" in text
    assert "per-category chart, suite mapping" in text


def test_report_from_run_folders(tmp_path):
    recs = _records(np.random.default_rng(2))
    for i, r in enumerate(recs):
        append_record(tmp_path / ("run-a" if i % 2 == 0 else "run-b") / "results.jsonl", r)
    path = write_report([tmp_path / "run-a", tmp_path / "run-b" / "results.jsonl"], tmp_path / "out")
    text = path.read_text()
    assert "- episodes: 60" in text and "## Suite `search`" in text
    assert all((tmp_path / "out" / n).is_file() for n in _links(text))


def test_report_compares_all_pairs_without_uses_map(tmp_path):
    recs = [make_record(run_id="r", suite="s", task="t", agent=a, encoder="e", episode_id=f"e{i}", seed=0,
                        status="ok", metrics={"success": (i + k) % 2 == 0})
            for i in range(6) for k, a in enumerate(["a", "b", "c"])]
    text = write_report(recs, tmp_path).read_text()
    assert "every pair of agents" in text
    assert text.count("| success | 6 |") == 3
    assert "paths_" not in text and "(extras.uses_map not recorded for all)" in text


def test_report_bad_input(tmp_path):
    with pytest.raises(ValueError, match="empty sequence"):
        write_report([], tmp_path)
    with pytest.raises(FileNotFoundError, match="no results at"):
        write_report(tmp_path / "nowhere", tmp_path)
    with pytest.raises(TypeError, match="got int"):
        write_report([3], tmp_path)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "results.jsonl").write_text("")
    with pytest.raises(ValueError, match="no records yet"):
        write_report(tmp_path / "empty", tmp_path)


def test_report_skips_unknown_scene(tmp_path):
    rec = make_record(run_id="r", suite="s", task="object_search", agent="nav", encoder="e", episode_id="e0", seed=0,
                      status="ok", metrics={"success": True},
                      extras={"scene": "household/nope.json", "path_xy": [[0, 0], [1, 1]]})
    text = write_report([rec], tmp_path).read_text()
    assert "floor plan of household/nope.json" in text
    assert any(n.startswith("paths_s_nav") for n in _links(text))
    assert Path(tmp_path / _links(text)[-1]).is_file()


def test_report_marks_privileged_results(tmp_path):
    recs = [make_record(run_id="r", suite="s", task="object_search", agent=a, encoder=e, episode_id=f"e{i}", seed=0,
                        status="ok", metrics={"success": i % 2 == 0}, extras={"privileged": p, "uses_map": True})
            for i in range(4) for a, e, p in (("map-navigator", "oracle-open", True), ("map-navigator", "embedded-v2", False))]
    text = write_report(recs, tmp_path).read_text()
    assert "- privileged (read ground truth a robot does not have): map-navigator (oracle-open)" in text
    assert "| map-navigator | oracle-open (privileged) | 4 |" in text
    assert "| map-navigator | embedded-v2 | 4 |" in text and "embedded-v2 (privileged)" not in text
    plain = [make_record(run_id="r", suite="s", task="t", agent="a", encoder="e", episode_id="e0", seed=0, status="ok",
                         metrics={"success": True})]
    assert "- privileged (read ground truth a robot does not have): none" in write_report(plain, tmp_path / "p").read_text()


def test_report_opens_each_suite_with_the_map_agent_against_its_twin(tmp_path):
    agents = (("map-navigator", {"uses_map": True}), ("twin-navigator", {"uses_map": False, "twin_of": "map-navigator"}),
              ("random-walker", {"uses_map": False}))
    recs = [make_record(run_id="r", suite="s", task="object_search", agent=a, encoder="e", episode_id=f"e{i}", seed=0,
                        status="ok", metrics={"success": (a == "map-navigator" and i < 5) or (a == "twin-navigator" and i < 2)},
                        extras=x)
            for i in range(8) for a, x in agents]
    text = write_report(recs, tmp_path).read_text()
    suite = text[text.index("## Suite `s`"):]
    # the first table of the suite is the matched pair, before the suite's own table
    assert suite.index("### Map agent against its matched map-free twin") < suite.index("| agent | encoder |")
    twins = suite[suite.index("### Map agent against its matched map-free twin"):suite.index("| agent | encoder |")]
    assert "| map-navigator (e) | twin-navigator (e) | success | 8 | 0.62 | 0.25 | +0.38 [" in twins and "| 3 / 0 |" in twins
    assert "random-walker" not in twins
    # the references follow; the twin pair is not repeated there
    refs = suite[suite.index("map-equipped agents against the weak and random references"):]
    assert "| map-navigator (e) | random-walker (e) | success |" in refs and "twin-navigator (e) | success" not in refs


def test_report_opens_on_the_headline_and_orders_suites_by_it(tmp_path):
    """The cards come first (twin comparisons before the rest), then the run summary, then each
    suite's section in the cards' order; a suite table ranks its agents by the headline metric."""
    recs = []
    for i in range(12):
        for agent, extras, win in (("map-navigator", {"uses_map": True}, i < 10),
                                   ("twin-navigator", {"uses_map": False, "twin_of": "map-navigator"}, i < 2)):
            recs.append(make_record(run_id="r", suite="b-search", task="object_search", agent=agent, encoder="e",
                                    episode_id=f"e{i}", seed=0, status="ok", metrics={"success": win}, extras=extras))
        recs.append(make_record(run_id="r", suite="a-maps", task="query", agent="mapper", encoder="e", episode_id=f"m{i}",
                                seed=0, status="ok", metrics={"miou": 0.5}))
    text = write_report(recs, tmp_path).read_text()
    order = [text.index(s) for s in ("## Headline", "| `b-search` |", "| `a-maps` |", "## Run summary", "## Suite `b-search`",
                                      "## Suite `a-maps`")]
    assert order == sorted(order)
    row = next(line for line in text.splitlines() if line.startswith("| `b-search` |"))
    assert "| map-navigator (e) | success 0.83 [" in row and "twin-navigator (matched map-free twin) 0.17" in row
    assert "| map helps |" in row and "p 0.0078 (exact McNemar), 12 pairs" in row
    suite = text[text.index("## Suite `b-search`"):]
    table = suite[suite.index("| agent | encoder | n | success |"):]
    assert table.index("| map-navigator |") < table.index("| twin-navigator |")  # the best first
    assert "failed/timeout" not in suite.split("## Suite")[1]  # every episode finished: no such column
