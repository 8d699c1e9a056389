"""Why episodes failed, in the report: the cause of each failure, the episode rows (goal, category,
cause; map suites by their headline metric), one failure page per suite grouped by cause, and what
the report says when replays are missing, a map's encoder is not installed, or a results file
mixes runs."""

import re
import struct
import warnings
from html.parser import HTMLParser

import numpy as np
import pytest

from harness.report.causes import CAUSES, failure_cause, is_failure, success_radius
from harness.report.failures import failures_file
from harness.report.html import write_reports
from harness.report.paths import replay_stem
from harness.runner.results import append_record, make_record, write_run_config


class _Page(HTMLParser):
    """Tables (id, head, rows of cell texts, row classes), every href/src, and h2 ids with their text."""

    def __init__(self):
        super().__init__()
        self.tables, self.links, self.videos, self.h2, self._cell, self._h2 = [], [], [], {}, None, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self.tables.append({"id": a.get("id"), "head": [], "rows": [], "kinds": []})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])
            self.tables[-1]["kinds"].append(a.get("class") or "")
        elif tag in ("td", "th"):
            self._cell = [tag, ""]
        elif tag == "video":
            self.videos.append(a)
        elif tag == "h2":
            self._h2 = [a.get("id"), ""]
        for key in ("href", "src"):
            if a.get(key):
                self.links.append(a[key])

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[1] += data
        if self._h2 is not None:
            self._h2[1] += data

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            t = self.tables[-1]
            (t["head"] if self._cell[0] == "th" else t["rows"][-1]).append(" ".join(self._cell[1].split()))
            self._cell = None
        elif tag == "h2" and self._h2 is not None:
            self.h2[self._h2[0]] = " ".join(self._h2[1].split())
            self._h2 = None


def _parse(path):
    p = _Page()
    p.feed(path.read_text(encoding="utf-8"))
    for t in p.tables:
        t["kinds"] = [k for k, r in zip(t["kinds"], t["rows"]) if r]
        t["rows"] = [r for r in t["rows"] if r]
    return p


def _search(run_id="A", **kw):
    base = dict(run_id=run_id, suite="search", task="object_search", agent="map-navigator", encoder="test", seed=0,
                status="ok", category="mug", timings={"wall_s": 1.0})
    base.update(kw)
    return make_record(**base)


# ---------------------------------------------------------------------------------------------- causes

@pytest.mark.parametrize("fields, expected", [
    (dict(status="timeout", error="exceeded 60 s"), "timeout"),
    (dict(status="failed", error="RuntimeError: x"), "error"),
    (dict(status="failed", error="x", extras={"stop_reason": "planner"}), "error"),  # the status wins
    (dict(metrics={"success": False}, extras={"stop_reason": "wrong_object"}), "wrong_object"),
    (dict(metrics={"success": True, "distance_to_goal": 0.2}), None),
    (dict(metrics={"success": False, "distance_to_goal": 0.6, "steps": 9, "collisions": 0}), "near_no_stop"),
    (dict(metrics={"success": False, "distance_to_goal": 1.5, "steps": 9, "collisions": 2}), "far"),
    (dict(metrics={"success": False, "distance_to_goal": 1.5, "steps": 9, "collisions": 2},
          extras={"success_radius": 2.0}), "near_no_stop"),  # the recorded radius, not the default 1 m
    (dict(metrics={"success": False, "distance_to_goal": 4.0, "steps": 10, "collisions": 5}), "stuck"),
    (dict(metrics={"success": False, "distance_to_goal": 4.0, "goals_reached": 1, "chain_length": 3}), "chain_partial"),
    (dict(metrics={"success": False, "steps": 3}), "unknown"),
    (dict(metrics={"text_miou": 0.1}), None),  # a map suite: no success metric, not a failure
])
def test_failure_cause(fields, expected):
    rec = _search(episode_id="e", **fields)
    assert failure_cause(rec) == expected
    assert is_failure(rec) == (expected is not None)
    assert expected is None or expected in CAUSES


def test_failure_cause_rejects_a_non_record_and_radius_defaults():
    with pytest.raises(TypeError, match="expected a results record \\(dict\\), got list"):
        failure_cause([])
    assert success_radius({"extras": {}}) == (1.0, False)
    assert success_radius({"extras": {"success_radius": 0.5}}) == (0.5, True)
    assert success_radius({"extras": {"success_radius": -1}}) == (1.0, False)


# ---------------------------------------------------------------------------------------------- a run

def _mp4(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x00\x00\x00\x18ftypmp42")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A run of two suites: ``search`` (two agents, failures of four causes, videos and maps of
    some) and the map suite ``query`` (no success metric)."""
    root = tmp_path_factory.mktemp("failures")
    folder = root / "run"
    write_run_config(folder, {"run_id": "A", "record": "failures"})
    recs = [
        _search(episode_id="s-0", metrics={"success": False, "distance_to_goal": 3.0, "steps": 50, "collisions": 0},
                extras={"goal": "the red mug by the sink", "stop_reason": "not_found", "success_radius": 1.0}),
        _search(episode_id="s-1", metrics={"success": False, "distance_to_goal": 2.0, "steps": 50, "collisions": 0},
                extras={"goal": "something to drink from", "stop_reason": "not_found"}, category="cup"),
        _search(episode_id="s-2", metrics={"success": True, "distance_to_goal": 0.4, "steps": 20, "collisions": 0},
                extras={"goal": "a bowl", "stop_reason": "reached"}, category="bowl"),
        _search(episode_id="s-3", status="timeout", error="episode exceeded 60 s", metrics={}),
        _search(episode_id="s-0", agent="random-walker", encoder="none",
                metrics={"success": False, "distance_to_goal": 5.0, "steps": 40, "collisions": 30}),
        _search(episode_id="s-1", agent="random-walker", encoder="none",
                metrics={"success": False, "distance_to_goal": 5.0, "steps": 40, "collisions": 1}),
    ]
    recs += [make_record(run_id="A", suite="query", task="map_query", agent="conceptfusion", encoder="test",
                         episode_id=f"scan-{i}", seed=0, status="ok", metrics={"text_miou": 0.25 * (i + 1), "n_objects": 4},
                         timings={"wall_s": 0.5}) for i in range(2)]
    for r in recs:
        append_record(folder / "results.jsonl", r)
    replays = folder / "replays"
    _mp4(replays / f"{replay_stem(recs[0])}.mp4")
    (replays / f"{replay_stem(recs[0])}.map.npz").write_bytes(b"PK\x03\x04")
    _mp4(replays / f"{replay_stem(recs[4])}.mp4")
    _mp4(replays / f"{replay_stem(recs[5])}.mp4")
    # recs[1] failed and the run recorded failures, but its video is gone: the report says so
    md, page = write_reports([folder], folder / "report")
    return folder, md, page, recs


def test_episode_rows_show_goal_category_and_cause(run):
    _, _, page, _ = run
    eps = {t["id"]: t for t in _parse(page).tables}["episodes-search"]
    head = eps["head"]
    assert head[:8] == ["agent", "encoder", "episode", "seed", "outcome", "cause", "goal", "category"]
    rows = {(r[0], r[2]): dict(zip(head, r)) for r in eps["rows"]}
    first = rows[("map-navigator", "s-0")]
    assert (first["outcome"], first["cause"], first["goal"], first["category"]) == (
        "miss", "not_found", "the red mug by the sink", "mug")
    assert rows[("map-navigator", "s-3")]["cause"] == "timeout"
    assert rows[("map-navigator", "s-2")]["cause"] == "-" and rows[("map-navigator", "s-2")]["outcome"] == "success"
    assert rows[("random-walker", "s-0")]["cause"] == "stuck" and rows[("random-walker", "s-1")]["cause"] == "far"
    assert rows[("random-walker", "s-0")]["goal"] == "-"  # no goal text recorded: the category says what it was


def test_map_suite_rows_give_their_headline_metric_not_a_miss(run):
    _, _, page, _ = run
    eps = {t["id"]: t for t in _parse(page).tables}["episodes-query"]
    outcomes = [r[eps["head"].index("outcome")] for r in eps["rows"]]
    assert sorted(outcomes) == ["text_miou 0.25", "text_miou 0.50"]
    assert all(k == "" for k in eps["kinds"])  # no miss or failed mark
    assert "cause" not in eps["head"] and "goal" not in eps["head"]  # columns none of its rows fills
    text = page.read_text()
    assert "Episodes of query: 2, no success metric" in text and "Episodes of query: 2, 2 not successful" not in text
    assert not (page.parent / failures_file("query")).exists()  # nothing failed there: no page


def test_failure_page_groups_by_cause_with_counts_videos_and_maps(run):
    folder, md, page, recs = run
    fail_page = page.parent / failures_file("search")
    assert fail_page.is_file()
    assert any(h.startswith(f"{fail_page.name}#cause-") for h in _parse(page).links)  # linked from the suite
    assert f"]({fail_page.name}#cause-not-found)" in md.read_text()
    parsed = _parse(fail_page)
    groups = {k: v for k, v in parsed.h2.items() if k and k.startswith("cause-")}
    assert list(groups) == ["cause-not_found".replace("_", "-"), "cause-timeout", "cause-stuck", "cause-far"]
    counts = {k: int(re.match(r"\S+: (\d+)", v).group(1)) for k, v in groups.items()}
    assert counts == {"cause-not-found": 2, "cause-timeout": 1, "cause-stuck": 1, "cause-far": 1}
    tables = [t for t in parsed.tables if t["head"][:2] == ["agent", "episode"]]
    assert [len(t["rows"]) for t in tables] == list(counts.values())  # each count is its episodes
    not_found = tables[0]
    assert not_found["rows"][0][2] == "the red mug by the sink" and not_found["rows"][1][3] == "cup"
    assert len(parsed.videos) == 3 and all(v.get("preload") == "none" and "controls" in v for v in parsed.videos)
    for link in parsed.links:
        if not link.startswith(("#", "report.html")):
            assert (fail_page.parent / link).resolve().is_file(), link
    text = fail_page.read_text()
    stem = replay_stem(recs[0])
    assert re.search(rf"cfharness view \S*{stem}\.map\.npz --encoder test", text)
    assert 'class="cf-copy"' in text


def test_a_missing_replay_is_marked_with_why(run):
    folder, _, page, recs = run
    eps = {t["id"]: t for t in _parse(page).tables}["episodes-search"]
    row = next(dict(zip(eps["head"], r)) for r in eps["rows"] if r[:3] == ["map-navigator", "test", "s-1"])
    assert row["replay"].startswith("missing") and "the run recorded failures" in row["replay"]
    assert "not in the run folder" in (page.parent / failures_file("search")).read_text()


def test_a_map_of_an_encoder_this_install_lacks_still_shows_its_command(tmp_path):
    rec = _search(episode_id="s-0", encoder="no-such-encoder", metrics={"success": False, "distance_to_goal": 3.0})
    append_record(tmp_path / "run" / "results.jsonl", rec)
    (tmp_path / "run" / "replays").mkdir()
    (tmp_path / "run" / "replays" / f"{replay_stem(rec)}.map.npz").write_bytes(b"PK\x03\x04")
    _, page = write_reports([tmp_path / "run"], tmp_path / "report")
    text = page.read_text()
    assert "--encoder no-such-encoder" in text
    assert "encoder &#x27;no-such-encoder&#x27; is not available in this install" in text
    fail = (tmp_path / "report" / failures_file("search")).read_text()
    assert "is not available in this install" in fail and "--encoder no-such-encoder" in fail


def test_a_results_file_mixing_runs_builds_and_says_which_rows_are_foreign(tmp_path):
    folder = tmp_path / "run"
    write_run_config(folder, {"run_id": "A", "record": "failures"})
    mine = _search(episode_id="s-0", metrics={"success": False, "distance_to_goal": 3.0})
    other = _search(run_id="B", episode_id="s-1", metrics={"success": False, "distance_to_goal": 3.0})
    for r in (mine, other):
        append_record(folder / "results.jsonl", r)
        _mp4(folder / "replays" / f"{replay_stem(r)}.mp4")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, page = write_reports([folder], tmp_path / "report")
    assert any("run" in str(w.message) for w in caught)  # results.warn_record_problems
    eps = {t["id"]: t for t in _parse(page).tables}["episodes-search"]
    replay = {r[2]: r[eps["head"].index("replay")] for r in eps["rows"]}
    assert "this record is of run B" in replay["s-1"] and "run B" not in replay["s-0"]


# ---------------------------------------------------------------------------------------------- figures

def _png_size(png: bytes) -> tuple[int, int]:
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", png[16:24])


def test_category_bars_fit_the_report_and_grow_with_categories():
    from harness.report.plots import category_bars

    few = {"a": {"mug": (0.5, 4), "cup": (1.0, 2)}, "b": {"mug": (0.25, 4)}}
    many = {"a": {f"category {i}": (i / 30, 3) for i in range(30)}, "b": {"mug": (1.0, 1)}}
    w_few, h_few = _png_size(category_bars(few, title="t"))
    w_many, h_many = _png_size(category_bars(many, title="t"))
    assert abs(w_few - 760) <= 12 and abs(w_many - 760) <= 12  # drawn at the width it is shown at
    assert h_many > 3 * h_few
    with pytest.raises(ValueError, match="no categories"):
        category_bars({"a": {}}, title="t")


def test_heatmap_of_the_new_file_format_is_cropped_and_judged(tmp_path):
    from harness.report.figures import read_heatmap
    from harness.report.plots import heatmap_topdown

    rng = np.random.default_rng(0)
    floor = np.c_[rng.uniform(-4, 4, (3000, 2)), np.zeros(3000)]
    table = np.c_[rng.uniform(-0.5, 0.5, (2000, 1)), rng.uniform(-0.3, 0.3, (2000, 1)), np.full(2000, 0.4)]
    pts = np.r_[floor, table]
    values = np.zeros(len(pts))
    on_obj = (np.abs(pts[:, 0] - 0.2) < 0.05) & (np.abs(pts[:, 1]) < 0.05) & (pts[:, 2] > 0.3)
    values[on_obj] = 0.9
    path = tmp_path / "heat.npz"
    np.savez(path, points=pts, values=values, query="red mug", object="obj0",
             gt_box=np.array([[0.15, -0.05, 0.4], [0.25, 0.05, 0.5]]), scene_box=np.array([[-0.5, -0.3, 0.35], [0.5, 0.3, 0.5]]),
             answer_indices=np.flatnonzero(on_obj), found=True, iou=0.6, iou_thresh=0.5, right_iou=0.25, version=2)
    view = read_heatmap(path, {"episode_id": "scan-0", "extras": {}})
    assert view.query == "red mug" and view.right is True and view.notes == []
    assert np.allclose(view.crop_xy, [[-0.56, -0.36], [0.56, 0.36]])  # the table, not the 8 m floor
    assert (view.points_n3[:, 2] > 0.3).all()  # the floor is left out
    assert view.verdict().startswith("found: right, IoU 0.60") and "brightest point is on the object" in view.verdict()
    png = heatmap_topdown(view.points_n3, view.values_n, title="q", crop_xy=view.crop_xy, gt_box_xy=view.gt_box_xy,
                          answer_box_xy=view.answer_box_xy, verdict=view.verdict(), verdict_ok=view.right)
    assert _png_size(png)[0] > 300
    with pytest.raises(ValueError, match=r"expected points \(N, 3\) and values \(N,\)"):
        heatmap_topdown(pts[:, :2], values, title="q")


def test_heatmap_of_the_old_file_format_takes_its_verdict_from_the_record(tmp_path):
    from harness.report.figures import read_heatmap

    pts = np.c_[np.random.default_rng(1).uniform(-0.6, 0.6, (500, 2)), np.full(500, 0.4)]
    path = tmp_path / "old.npz"
    np.savez(path, points=pts, values=np.zeros(500), query="black domino")
    rec = {"episode_id": "tabletop-v2-300005", "extras": {"queries": [
        {"object": "obj0", "name": "black domino", "text": {"iou": 0.0, "iou_thresh": 0.0, "found": False}}]}}
    view = read_heatmap(path, rec)
    assert view.found is False and view.right is False and view.verdict().startswith("not found")
    assert view.gt_box_xy is not None  # the object's footprint, from the shipped scene file
    assert any("older heatmap file" in n for n in view.notes)


def test_the_query_suite_writes_the_new_heatmap_file(tmp_path):
    from harness.maps.query import HEATMAP_VERSION, run_query_scene

    metrics, extras, _ = run_query_scene("tabletop-0111", "color", frames=4, width=64, height=48,
                                         heatmap_path=tmp_path / "h.npz")
    with np.load(tmp_path / "h.npz") as h:
        first = extras["queries"][0]
        assert int(h["version"]) == HEATMAP_VERSION and str(h["query"]) == first["name"] and str(h["object"]) == first["object"]
        assert h["points"].shape == (metrics["map_points"], 3) and h["values"].shape == (metrics["map_points"],)
        assert bool(h["found"]) == first["text"]["found"] and round(float(h["iou"]), 4) == first["text"]["iou"]
        lo, hi = h["gt_box"]
        assert (lo < hi).all() and (h["scene_box"][0] <= lo).all() and (h["scene_box"][1] >= hi).all()
        assert h["answer_indices"].size == 0 or bool(h["found"])
