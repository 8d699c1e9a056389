"""The HTML report: the headline cards first, every table of the Markdown report (column groups in a
two-row header, the wide ones partly hidden), self-contained, episodes failures first with links to
replay videos and maps that exist, several runs side by side, and a size bound."""

import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from harness.report.document import Card, Cards, Cell, ReportDocument, Table, render_markdown
from harness.report.html import HTML_FILE, render_html, write_reports
from harness.report.paths import replay_stem
from harness.runner.results import append_record, make_record


class _Tables(HTMLParser):
    """Every <table>: its id, column names (``group: column`` for grouped columns, in column
    order), rows (cell texts), which body columns start hidden; the page's cards (their text),
    links and images."""

    def __init__(self):
        super().__init__()
        self.tables, self.links, self.images, self.scripts, self.cards, self._cell = [], [], [], [], [], None
        self._card_depth = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "article" and "card" in (a.get("class") or ""):
            self.cards.append({"suite": a.get("data-suite"), "class": a.get("class"), "text": ""})
            self._card_depth = 1
        elif self._card_depth and tag == "article":
            self._card_depth += 1
        if tag == "table":
            self.tables.append({"id": a.get("id"), "ths": [], "rows": [], "kinds": [], "hidden_cols": set()})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])
            self.tables[-1]["kinds"].append(a.get("class") or "")
        elif tag == "th":
            self._cell = [tag, "", a]
        elif tag == "td":
            self._cell = [tag, "", a]
            if "hidden" in a:
                self.tables[-1]["hidden_cols"].add(len(self.tables[-1]["rows"][-1]))
        elif tag == "a":
            self.links.append(a.get("href"))
        elif tag == "img":
            self.images.append(a.get("src"))
        elif tag in ("script", "link"):
            self.scripts.append(a)

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[1] += data
        if self._card_depth:
            self.cards[-1]["text"] += data

    def handle_endtag(self, tag):
        if tag == "article" and self._card_depth:
            self._card_depth -= 1
        if tag in ("td", "th") and self._cell is not None:
            t = self.tables[-1]
            if self._cell[0] == "th":
                t["ths"].append((self._cell[1].strip(), self._cell[2]))
            else:
                t["rows"][-1].append(self._cell[1].strip())
            self._cell = None


def _parse(text):
    p = _Tables()
    p.feed(text)
    for t in p.tables:
        t["kinds"] = [k for k, r in zip(t["kinds"], t["rows"]) if r]
        t["rows"] = [r for r in t["rows"] if r]
        groups = {a["data-group"]: text for text, a in t["ths"] if a.get("class") == "group"}
        cols = sorted((int(a["data-col"]), f"{groups[a['data-group']]}: {text}" if a.get("data-group") else text, "hidden" in a)
                      for text, a in t["ths"] if "data-col" in a)
        t["head"] = [name for _, name, _ in cols]
        t["hidden_head"] = {i for i, _, hidden in cols if hidden}
    return p


def _md_tables(text):
    """(header, rows) of every Markdown table, cells unescaped and links as their text."""
    out, lines = [], text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("|") and i + 1 < len(lines) and lines[i + 1].startswith("|---"):
            split = lambda l: [re.sub(r"^\[(.*)\]\([^)]*\)$", r"\1", c.strip()).replace("\\|", "|")
                               for c in re.split(r"(?<!\\)\|", l)[1:-1]]
            rows, j = [], i + 2
            while j < len(lines) and lines[j].startswith("|"):
                rows.append(split(lines[j]))
                j += 1
            out.append((split(line), rows))
    return out


def _run(folder: Path, run_id: str, rng, with_replays: bool):
    """A run folder with search episodes of two agents; replays (a video and a map) of failures."""
    for i in range(12):
        for agent, rate, uses_map in (("map-navigator", 0.7, True), ("random-walker", 0.2, False)):
            crashed = agent == "random-walker" and i == 3
            win = bool(rng.random() < rate) and not crashed
            rec = make_record(run_id=run_id, suite="search", task="object_search", agent=agent, encoder="test",
                              episode_id=f"search-{i:04d}", seed=0, status="failed" if crashed else "ok",
                              error="RuntimeError: the | pipe broke" if crashed else None, category=("mug", "box")[i % 2],
                              metrics={} if crashed else {"success": win, "spl": 0.8 * win, "steps": 30 + i},
                              timings={"wall_s": 1.5}, extras={"uses_map": uses_map})
            append_record(folder / "results.jsonl", rec)
            if with_replays and not win:
                (folder / "replays").mkdir(parents=True, exist_ok=True)
                (folder / "replays" / f"{replay_stem(rec)}.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42")
                if agent == "map-navigator":
                    (folder / "replays" / f"{replay_stem(rec)}.map.npz").write_bytes(b"PK\x03\x04")


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("html")
    _run(root / "runA", "A", np.random.default_rng(0), with_replays=True)
    _run(root / "runB", "B", np.random.default_rng(1), with_replays=False)
    md, page = write_reports([root / "runA", root / "runB"], root / "report", title="Two runs")
    return root, md, page


def test_html_holds_every_table_of_the_markdown_report(two_runs):
    _, md, page = two_runs
    assert page.name == HTML_FILE and page.parent == md.parent
    md_tables = [t for t in _md_tables(md.read_text()) if t[0][:2] != ["suite", "question"]]  # the headline: cards
    html_tables = _parse(page.read_text()).tables
    assert len(md_tables) >= 3  # suite table, runs side by side, paired comparisons
    for head, rows in md_tables:
        match = [t for t in html_tables if t["head"] == head]
        assert match, f"no HTML table with the header {head}"
        assert any(t["rows"] == rows for t in match), f"HTML rows differ for the table {head}"


def test_html_is_self_contained(two_runs):
    _, md, page = two_runs
    text = page.read_text()
    parsed = _parse(text)
    assert text.startswith("<!DOCTYPE html>") and "<style>" in text
    assert not re.search(r"(src|href)=\"(https?:)?//", text), "the page must not fetch anything from the network"
    assert all("src" not in s and "href" not in s for s in parsed.scripts)  # inline scripts only, no stylesheet links
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", md.read_text())
    assert figures and len(parsed.images) == len(figures)
    assert all(src.startswith("data:image/png;base64,") for src in parsed.images)


def test_episodes_failures_first_with_replay_and_map_links(two_runs):
    root, _, page = two_runs
    tables = {t["id"]: t for t in _parse(page.read_text()).tables}
    eps = tables["episodes-search"]
    assert eps["head"][:6] == ["run", "agent", "encoder", "episode", "seed", "outcome"]
    assert eps["head"][-4:] == ["s", "error", "replay", "map"]
    assert len(eps["rows"]) == 48  # 2 runs x 2 agents x 12 episodes: runs are not merged here
    order = {"kind-failed": 0, "kind-miss": 1, "kind-success": 2}
    ranks = [order[k] for k in eps["kinds"]]
    assert ranks == sorted(ranks) and ranks[0] == 0 and ranks[-1] == 2
    first = eps["rows"][0]
    assert first[5] == "failed" and first[eps["head"].index("error")] == "RuntimeError: the | pipe broke"
    links = [h for h in _parse(page.read_text()).links if h.endswith((".mp4", ".map.npz"))]
    assert links and all(not h.startswith("/") for h in links)
    for href in links:  # relative to the report folder, naming files that exist
        assert (page.parent / href).resolve().is_file(), href
    n_videos = len(list((root / "runA" / "replays").glob("*.mp4")))
    assert sum(h.endswith(".mp4") for h in links) == n_videos
    video_rows = [r for r in eps["rows"] if r[-2] == "video"]
    assert video_rows and all(r[0].endswith("runA") and r[5] in ("miss", "failed") for r in video_rows)


def test_runs_side_by_side(two_runs):
    root, md, page = two_runs
    t = {t["id"]: t for t in _parse(page.read_text()).tables}["runs-search"]
    assert t["head"] == ["agent", "encoder", f"{root / 'runA'}: success [95% CI] (n)", f"{root / 'runB'}: success [95% CI] (n)"]
    assert [r[0] for r in t["rows"]] == ["map-navigator", "random-walker"]
    assert all(re.fullmatch(r"\d\.\d\d \[\d\.\d\d, \d\.\d\d\] \(12\)", c) for r in t["rows"] for c in r[2:])
    assert "### Runs side by side" in md.read_text()


def test_one_run_has_no_side_by_side_table_and_markdown_has_no_episode_rows(tmp_path):
    _run(tmp_path / "run", "A", np.random.default_rng(0), with_replays=False)
    md, page = write_reports([tmp_path / "run"], tmp_path / "report")
    assert "Runs side by side" not in md.read_text() and "runs-search" not in page.read_text()
    assert "search-0003" not in md.read_text() and "search-0003" in page.read_text()


def test_cells_are_escaped_and_sort_keys_written():
    doc = ReportDocument(title="<t>", out_dir=Path("."), figures={}, items=[], blocks=[
        Table(("name", "value"), [("<b>x</b>", Cell("0.50 [0.1, 0.9]", sort=0.5, interval=(0.5, 0.1, 0.9))),
                                  ("y", Cell("-", sort=float("nan")))], name="t")])
    text = render_html(doc)
    assert "&lt;b&gt;x&lt;/b&gt;" in text and "<b>x</b>" not in text and "<title>&lt;t&gt;</title>" in text
    assert 'data-sort="0.5"' in text and 'data-sort=""' in text and 'class="ci-range" style="left:10.0%;width:80.0%"' in text
    assert "| <b>x</b> | 0.50 [0.1, 0.9] |" in render_markdown(doc)
    with pytest.raises(ValueError, match="row 0 has 1 cells, expected 2"):
        Table(("a", "b"), [("only",)])


def test_default_comparison_sized_report_is_small(tmp_path):
    """About the default comparison's size: 5 suites, 3 agents, 50-150 episodes each."""
    rng = np.random.default_rng(0)
    recs = []
    for suite, n in (("query", 10), ("ablation", 40), ("spatial", 20), ("rearrange", 150), ("search", 50)):
        for agent in ("map-agent", "frame-agent", "random-agent"):
            for i in range(n):
                ok = bool(rng.random() < 0.5)
                recs.append(make_record(run_id="r", suite=suite, task="t", agent=agent, encoder="embedded",
                                        episode_id=f"{suite}-{i:04d}", seed=0, status="ok",
                                        metrics={"success": ok, "spl": float(ok) * rng.random()},
                                        timings={"wall_s": 2.0}, extras={"uses_map": agent == "map-agent"}))
    md, page = write_reports(recs, tmp_path / "report")
    size = page.stat().st_size
    assert size < 20 * 2**20, f"report.html is {size / 2**20:.1f} MB"
    tables = {t["id"]: t for t in _parse(page.read_text()).tables}
    assert len(tables["episodes-search"]["rows"]) == 150 and len(tables["episodes-rearrange"]["rows"]) == 450


def test_the_page_opens_on_the_cards_and_markdown_on_their_table(two_runs):
    _, md, page = two_runs
    text = page.read_text()
    parsed = _parse(text)
    assert text.index('<section class="cards"') < text.index('id="run-summary"') < text.index('id="suite-search"')
    (card,) = parsed.cards
    assert card["suite"] == "search" and "map-navigator (test)" in card["text"] and "success" in card["text"]
    assert 'href="#section-search"' in text and 'id="section-search"' in text  # the card links its section
    md_text = md.read_text()
    head, rows = _md_tables(md_text)[0]
    assert head == ["suite", "question", "best", "figure", "against", "difference [95% CI]", "test", "verdict"]
    assert md_text.index("## Headline") < md_text.index("## Run summary") < md_text.index("## Suite `search`")
    assert rows[0][0] == "`search`" and rows[0][2] == "map-navigator (test)" and rows[0][2] in card["text"]


def _grouped_doc():
    head = ("agent", "n", "mIoU", "found", "mIoU", "found", "s")
    groups = ("", "", "name", "name", "held-out category", "held-out category", "")
    rows = [("a", Cell("3", sort=3), "0.5", "0.6", "0.1", "0.2", "1 s")]
    return ReportDocument(title="t", out_dir=Path("."), figures={}, items=[], blocks=[
        Table(head, rows, name="g", groups=groups, collapsed=("held-out category",))])


def test_grouped_columns_have_a_two_row_header_and_start_hidden_when_collapsed():
    doc = _grouped_doc()
    text = render_html(doc)
    (t,) = _parse(text).tables
    assert t["head"] == ["agent", "n", "name: mIoU", "name: found", "held-out category: mIoU", "held-out category: found", "s"]
    assert t["hidden_head"] == {4, 5} and t["hidden_cols"] == {4, 5}  # the collapsed group's header and cells
    assert 'rowspan="2"' in text and 'colspan="2" data-group="g1">name</th>' in text
    assert re.search(r'<th scope="colgroup" class="group" colspan="2" data-group="g2" hidden>held-out category</th>', text)
    assert 'aria-pressed="true" data-default="shown"' in text and 'data-group="g2" aria-pressed="false"' in text
    assert re.search(r'<th scope="col" data-col="0" rowspan="2" class="pin">agent</th>', text) and '<td class="pin">a</td>' in text
    md = render_markdown(doc)  # the archive keeps every column, named in full
    assert "| agent | n | name: mIoU | name: found | held-out category: mIoU | held-out category: found | s |" in md


def test_table_groups_are_checked():
    with pytest.raises(ValueError, match="2 group names for 3 columns"):
        Table(("a", "b", "c"), [], groups=("", "x"))
    with pytest.raises(ValueError, match="columns of a group must be adjacent"):
        Table(("a", "b", "c"), [], groups=("x", "", "x"))
    with pytest.raises(ValueError, match=r"collapsed groups \['y'\] are not groups of the table"):
        Table(("a", "b"), [], groups=("", "x"), collapsed=("y",))


def test_cards_are_escaped_and_marked_by_their_verdict():
    card = Card(title="s<1>", question="Does <b> help?", best="a (e)", figure="success 0.50", against="b (twin) 0.25",
                difference="+0.25 [+0.10, +0.40]", test="p 0.01", verdict="map helps", tone="better", href="#section-s")
    text = render_html(ReportDocument(title="t", out_dir=Path("."), figures={}, items=[], blocks=[Cards((card,))]))
    assert "Does &lt;b&gt; help?" in text and "<b> help" not in text and "s&lt;1&gt;" in text
    (c,) = _parse(text).cards
    assert "tone-better" in c["class"] and "map helps" in c["text"] and "+0.25 [+0.10, +0.40]" in c["text"]
    md = render_markdown(ReportDocument(title="t", out_dir=Path("."), figures={}, items=[], blocks=[Cards((card,))]))
    assert "| `s<1>` | Does <b> help? | a (e) | success 0.50 | b (twin) 0.25 | +0.25 [+0.10, +0.40] | p 0.01 | map helps |" in md
