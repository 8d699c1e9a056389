"""The report as one self-contained HTML page (``report.html``).

The page is built from the same :class:`~harness.report.document.ReportDocument` as the
Markdown report, so it holds every table of it, plus one table per suite with a row per episode
(failures first) linking each episode's replay video and map. It opens from disk with no server
and reaches nothing outside itself: CSS and JavaScript are inline, figures are inline PNG data,
and only the replay videos and maps are links to files beside the run (relative paths).

The page opens on the headline: a grid of cards, one per suite, each answering the suite's
question (:mod:`harness.report.cards`) and linking its section. Every table sorts by a click on a
column header (again: the other way); its first column (the agent) stays in view when a wide
table scrolls sideways; a table with column groups has a two-row header and a button per group
that shows or hides its columns (wide tables start with the headline's group only); a rate's
interval is drawn as a small bar in its cell; the episode tables have a filter box.
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from pathlib import Path

from conceptfusion.io_utils import atomic_write_text
from harness.report.document import Bullets, Card, Cards, Cell, Figure, Heading, Paragraph, ReportDocument, Table
from harness.report.markdown import build_report, write_markdown
from harness.report.widgets import WIDGET_CSS, WIDGET_JS, command_html

__all__ = ["HTML_FILE", "render_html", "write_html", "write_html_report", "write_reports"]

HTML_FILE = "report.html"
"""Name of the HTML report inside the report folder."""

_CSS = """
:root { --fg: #1d2430; --muted: #5b6575; --line: #d8dde6; --head: #eef1f6; --accent: #2f6fdb; --bad: #c0392b; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg);
       margin: 0 auto; max-width: 1280px; padding: 16px 24px 48px; }
h1 { font-size: 24px; margin: 8px 0 4px; } h2 { font-size: 19px; margin: 32px 0 8px; border-bottom: 1px solid var(--line); }
h3 { font-size: 15px; margin: 20px 0 6px; } code { background: var(--head); padding: 0 4px; border-radius: 3px; }
nav { font-size: 13px; color: var(--muted); } nav a { margin-right: 12px; }
a { color: var(--accent); }
.table-wrap { overflow-x: auto; margin: 6px 0 10px; }
table { border-collapse: collapse; font-size: 13px; }
th, td { border: 1px solid var(--line); padding: 3px 8px; text-align: left; vertical-align: top; white-space: nowrap; }
th { background: var(--head); user-select: none; position: sticky; top: 0; }
th[data-col] { cursor: pointer; } th.group { text-align: center; color: var(--muted); font-weight: 600; }
[hidden] { display: none !important; }
.pin { position: sticky; left: 0; z-index: 1; background: #fff; box-shadow: 1px 0 0 var(--line); }
th.pin { background: var(--head); z-index: 2; }
.groups { font-size: 12px; color: var(--muted); margin: 4px 0 2px; }
.groups button { font: inherit; padding: 1px 8px; margin: 0 4px 4px 0; border: 1px solid var(--line); border-radius: 10px;
                 background: #fff; color: var(--muted); cursor: pointer; }
.groups button[aria-pressed="true"] { background: #e3ecfb; border-color: #9dbcf0; color: var(--fg); }
.cards { display: grid; grid-template-columns: repeat(auto-fill, minmax(360px, 1fr)); gap: 10px; margin: 8px 0 4px; }
.card { border: 1px solid var(--line); border-top: 4px solid #b8c0cc; border-radius: 6px; padding: 8px 10px;
        font-size: 13px; line-height: 1.35; }
.card.tone-better { border-top-color: #2e9e5b; } .card.tone-worse { border-top-color: var(--bad); }
.card.tone-same { border-top-color: #8a94a6; }
.card header { display: flex; justify-content: space-between; align-items: baseline; gap: 6px; }
.card header a { font-weight: 600; text-decoration: none; white-space: nowrap; }
.card .verdict { font-weight: 600; font-size: 12px; padding: 0 6px; border-radius: 8px; background: #eef1f6; text-align: right; }
.tone-better .verdict { background: #dff3e6; color: #1e6e3e; } .tone-worse .verdict { background: #f8e0dd; color: #8e2a20; }
.card .question { margin: 4px 0 6px; font-weight: 600; }
.card dl { margin: 0; display: grid; grid-template-columns: max-content 1fr; column-gap: 8px; row-gap: 2px; }
.card dt { color: var(--muted); } .card dd { margin: 0; } .card .test, .card .note { color: var(--muted); font-size: 12px; }
.card .note { margin: 4px 0 0; }
th[aria-sort="ascending"]::after { content: " \\25B2"; font-size: 10px; }
th[aria-sort="descending"]::after { content: " \\25BC"; font-size: 10px; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.err { white-space: normal; max-width: 360px; color: var(--bad); }
tr.kind-failed td:first-child { border-left: 3px solid var(--bad); }
tr.kind-miss td:first-child { border-left: 3px solid #e6a23c; }
.ci { display: inline-block; position: relative; width: 64px; height: 8px; background: #f0f2f5;
      margin-right: 6px; vertical-align: middle; border-radius: 2px; }
.ci-range { position: absolute; top: 0; height: 8px; background: #9dbcf0; border-radius: 2px; }
.ci-mean { position: absolute; top: -2px; width: 2px; height: 12px; background: var(--accent); }
figure { margin: 8px 0; } figure img { max-width: min(100%, 760px); border: 1px solid var(--line); }
details > summary { cursor: pointer; color: var(--muted); margin: 6px 0; }
input.filter { margin: 4px 0; padding: 3px 6px; width: 280px; }
"""

_JS = r"""
(function () {
  function key(td) {
    if (!td) return null;
    var s = td.getAttribute('data-sort');
    if (s === null) return td.textContent.trim().toLowerCase();
    if (s === '') return null;
    var v = Number(s);
    return isNaN(v) ? s.toLowerCase() : v;
  }
  function compare(a, b) {
    if (a === null && b === null) return 0;
    if (a === null) return 1;
    if (b === null) return -1;
    if (typeof a === typeof b) return a < b ? -1 : a > b ? 1 : 0;
    return typeof a === 'number' ? -1 : 1;
  }
  function sortBy(th) {
    var table = th.closest('table'), body = table.tBodies[0], col = Number(th.getAttribute('data-col'));
    var dir = th.getAttribute('aria-sort') === 'ascending' ? -1 : 1;
    table.querySelectorAll('th[aria-sort]').forEach(function (h) { h.removeAttribute('aria-sort'); });
    th.setAttribute('aria-sort', dir === 1 ? 'ascending' : 'descending');
    var rows = Array.prototype.slice.call(body.rows).map(function (tr, i) { return [key(tr.cells[col]), i, tr]; });
    rows.sort(function (x, y) {
      var c = compare(x[0], y[0]);
      if (x[0] !== null && y[0] !== null) c *= dir;  // empty cells stay last either way
      return c || x[1] - y[1];
    });
    rows.forEach(function (r) { body.appendChild(r[2]); });
  }
  document.querySelectorAll('table.sortable th[data-col]').forEach(function (th) {
    th.addEventListener('click', function () { sortBy(th); });
  });
  function showGroup(table, group, show) {
    table.querySelectorAll('[data-group="' + group + '"]').forEach(function (c) { c.hidden = !show; });
  }
  document.querySelectorAll('.groups').forEach(function (bar) {
    var table = document.getElementById(bar.getAttribute('data-table'));
    var buttons = Array.prototype.slice.call(bar.querySelectorAll('button[data-group]'));
    var all = bar.querySelector('button.all');
    function sync() {
      if (all) all.setAttribute('aria-pressed', String(buttons.every(function (b) { return b.getAttribute('aria-pressed') === 'true'; })));
    }
    buttons.forEach(function (b) {
      b.addEventListener('click', function () {
        var show = b.getAttribute('aria-pressed') !== 'true';
        b.setAttribute('aria-pressed', String(show));
        showGroup(table, b.getAttribute('data-group'), show);
        sync();
      });
    });
    if (all) all.addEventListener('click', function () {
      var show = all.getAttribute('aria-pressed') !== 'true';
      buttons.forEach(function (b) {
        var on = show || b.getAttribute('data-default') === 'shown';
        b.setAttribute('aria-pressed', String(on));
        showGroup(table, b.getAttribute('data-group'), on);
      });
      sync();
    });
  });
  document.querySelectorAll('input.filter').forEach(function (input) {
    input.addEventListener('input', function () {
      var words = input.value.toLowerCase().split(/\s+/).filter(Boolean);
      var body = document.getElementById(input.getAttribute('data-table')).tBodies[0];
      Array.prototype.forEach.call(body.rows, function (tr) {
        var text = tr.textContent.toLowerCase();
        tr.hidden = !words.every(function (w) { return text.indexOf(w) >= 0; });
      });
    });
  });
})();
"""

_OPEN_ROWS = 50
"""HTML-only tables with more rows start folded."""


def _inline(text: str) -> str:
    """Escaped text with Markdown code spans as ``<code>``."""
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text))


def _slug(text: str, used: set[str]) -> str:
    base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"
    slug, i = base, 1
    while slug in used:
        i += 1
        slug = f"{base}-{i}"
    used.add(slug)
    return slug


def _sort_attr(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and not math.isfinite(value):
        return ' data-sort=""'
    return f' data-sort="{html.escape(str(value))}"'


def _interval_bar(mean: float, low: float, high: float) -> str:
    pct = [100.0 * min(max(float(v), 0.0), 1.0) for v in (mean, low, high)]
    return (f'<span class="ci" aria-hidden="true"><span class="ci-range" style="left:{pct[1]:.1f}%;'
            f'width:{max(pct[2] - pct[1], 0.5):.1f}%"></span><span class="ci-mean" style="left:{pct[0]:.1f}%">'
            "</span></span>")


def _td(cell: Cell | str, wrap: bool = False, extra: str = "", pin: bool = False) -> str:
    """One body cell; ``extra``: more attributes (its column group), ``pin``: the column that stays in view."""
    c = cell if isinstance(cell, Cell) else Cell(str(cell))
    text = html.escape(c.text)
    if c.href:
        text = f'<a href="{html.escape(c.href)}">{text}</a>'
    if c.interval is not None:
        text = _interval_bar(*c.interval) + text
    if c.command:
        text += " " + command_html(c.command, c.note or "")
    elif c.note:
        text += f'<span class="cf-note">{html.escape(c.note)}</span>'
    classes = ["pin"] if pin else []
    if isinstance(c.sort, (int, float)) and not isinstance(c.sort, bool):
        classes.append("num")
    if wrap:
        classes.append("err")
    cls = f' class="{" ".join(classes)}"' if classes else ""
    title = f' title="{html.escape(c.title)}"' if c.title else ""
    return f"<td{cls}{_sort_attr(c.sort)}{title}{extra}>{text}</td>"


def _group_ids(t: Table) -> list[str]:
    """Per column, the ``data-group`` id of its group (``g1``, ``g2``, ...; ``""``: in no group)."""
    ids, names = [], {}
    for g in t.groups or ("",) * len(t.head):
        ids.append(names.setdefault(g, f"g{len(names) + 1}") if g else "")
    return ids


def _head(t: Table, gids: list[str]) -> str:
    """The header: one row, or with groups two (group names over their columns; columns in no
    group span both rows)."""
    def col(i: int, rowspan: str = "") -> str:
        hidden = " hidden" if t.groups and t.groups[i] in t.collapsed else ""
        group = f' data-group="{gids[i]}"' if gids[i] else ""
        pin = ' class="pin"' if i == 0 else ""
        return f'<th scope="col" data-col="{i}"{rowspan}{group}{pin}{hidden}>{html.escape(t.head[i])}</th>'

    if not any(gids):
        return "<tr>" + "".join(col(i) for i in range(len(t.head))) + "</tr>"
    top, bottom, i = [], [], 0
    while i < len(t.head):
        if not gids[i]:
            top.append(col(i, ' rowspan="2"'))
            i += 1
            continue
        j = i
        while j < len(t.head) and gids[j] == gids[i]:
            j += 1
        hidden = " hidden" if t.groups[i] in t.collapsed else ""
        top.append(f'<th scope="colgroup" class="group" colspan="{j - i}" data-group="{gids[i]}"{hidden}>'
                   f"{html.escape(t.groups[i])}</th>")
        bottom += [col(k) for k in range(i, j)]
        i = j
    return f"<tr>{''.join(top)}</tr><tr>{''.join(bottom)}</tr>"


def _group_bar(t: Table, gids: list[str], table_id: str) -> str:
    """A button per column group (pressed: shown), and one that shows them all."""
    seen = {}
    for g, gid in zip(t.groups, gids):
        if gid:
            seen.setdefault(gid, [g, 0])[1] += 1
    buttons = "".join(
        f'<button type="button" data-group="{gid}" aria-pressed="{str(g not in t.collapsed).lower()}" '
        f'data-default="{"hidden" if g in t.collapsed else "shown"}" title="show or hide the {n} column(s) of {html.escape(g)}">'
        f"{html.escape(g)} ({n})</button>" for gid, (g, n) in seen.items())
    everything = f'<button type="button" class="all" aria-pressed="{str(not t.collapsed).lower()}">all</button>'
    return f'<div class="groups" data-table="{table_id}">column groups: {buttons}{everything}</div>'


def _table(t: Table, table_id: str) -> str:
    gids = _group_ids(t)
    cell_attrs = [(f' data-group="{g}"' if g else "") + (" hidden" if g and t.groups[i] in t.collapsed else "")
                  for i, g in enumerate(gids)]
    kinds = t.row_kinds or ("",) * len(t.rows)
    body = "\n".join((f'<tr class="kind-{html.escape(k)}">' if k else "<tr>")
                     + "".join(_td(c, h == "error", a, i == 0) for i, (h, c, a) in enumerate(zip(t.head, row, cell_attrs)))
                     + "</tr>" for k, row in zip(kinds, t.rows))
    table = (f'<div class="table-wrap"><table class="sortable" id="{table_id}"><thead>{_head(t, gids)}</thead>'
             f"<tbody>\n{body}\n</tbody></table></div>")
    if any(gids):
        table = _group_bar(t, gids, table_id) + table
    if t.markdown:
        return (f"<p><em>{_inline(t.caption)}</em></p>" if t.caption else "") + table
    filt = (f'<input class="filter" type="search" placeholder="filter rows (words)" data-table="{table_id}" '
            f'aria-label="filter {html.escape(t.caption or table_id)}">')
    return (f'<details{" open" if len(t.rows) <= _OPEN_ROWS else ""}><summary>{_inline(t.caption or t.name)}'
            f"</summary>{filt}{table}</details>")


def _card(c: Card) -> str:
    title = f"<code>{html.escape(c.title)}</code>"
    title = f'<a href="{html.escape(c.href)}">{title}</a>' if c.href else title
    verdict = f'<span class="verdict">{html.escape(c.verdict)}</span>' if c.verdict else ""
    bar = _interval_bar(*c.interval) if c.interval is not None else ""
    rows = [("best", f"<strong>{html.escape(c.best)}</strong>"), ("", f"{bar}{html.escape(c.figure)}")]
    if c.against:
        rows.append(("against", html.escape(c.against)))
    if c.difference:
        rows.append(("difference", f"<strong>{html.escape(c.difference)}</strong>"
                                   + (f'<br><span class="test">{html.escape(c.test)}</span>' if c.test else "")))
    dl = "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in rows)
    note = f'<p class="note">{_inline(c.note)}</p>' if c.note else ""
    tone = f" tone-{html.escape(c.tone)}" if c.tone else ""
    return (f'<article class="card{tone}" data-suite="{html.escape(c.title)}"><header>{title}{verdict}</header>'
            f'<p class="question">{html.escape(c.question)}</p><dl>{dl}</dl>{note}</article>')


def _cards(block: Cards, section_id: str) -> str:
    return f'<section class="cards" id="{section_id}">' + "".join(_card(c) for c in block.cards) + "</section>"


def _figure(f: Figure, figures: dict[str, bytes]) -> str:
    png = figures.get(f.file)
    src = f"data:image/png;base64,{base64.b64encode(png).decode('ascii')}" if png is not None else html.escape(f.file)
    return f'<figure><img src="{src}" alt="{html.escape(f.alt)}"></figure>'


def render_html(doc: ReportDocument) -> str:
    """The page's HTML text (UTF-8): title, a contents line, then every block in order."""
    used: set[str] = set()
    anchors = {id(b): _slug(b.anchor, used) for b in doc.blocks if isinstance(b, Heading) and b.anchor}  # links to them first
    table_ids = {id(b): _slug(b.name or "table", used) for b in doc.blocks if isinstance(b, (Table, Cards))}  # stable ids next
    parts, nav = [], []
    for block in doc.blocks:
        if isinstance(block, Heading):
            slug = anchors.get(id(block)) or _slug(block.text, used)
            level = min(max(block.level, 2), 4)
            if level == 2:
                nav.append(f'<a href="#{slug}">{_inline(block.text)}</a>')
            parts.append(f'<h{level} id="{slug}">{_inline(block.text)}</h{level}>')
        elif isinstance(block, Paragraph):
            parts.append(f"<p>{_inline(block.text)}</p>")
        elif isinstance(block, Bullets):
            parts.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in block.items) + "</ul>")
        elif isinstance(block, Table):
            parts.append(_table(block, table_ids[id(block)]))
        elif isinstance(block, Cards):
            parts.append(_cards(block, table_ids[id(block)]))
        elif isinstance(block, Figure):
            parts.append(_figure(block, doc.figures))
        else:
            raise TypeError(f"report block: expected Heading, Paragraph, Bullets, Table, Figure or Cards, got {type(block).__name__}")
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html.escape(doc.title)}</title><style>{_CSS}{WIDGET_CSS}</style></head><body>",
        f"<h1>{html.escape(doc.title)}</h1>", "<nav>" + "".join(nav) + "</nav>", *parts,
        f"<script>{_JS}{WIDGET_JS}</script>", "</body></html>", "",
    ])


def write_html(doc: ReportDocument) -> Path:
    """Write ``doc.out_dir/report.html`` (atomically); returns its path."""
    return atomic_write_text(Path(doc.out_dir) / HTML_FILE, render_html(doc))


def write_html_report(run_dirs_or_records, out_dir: str | os.PathLike, *, title: str = "ConceptFusion harness report",
                      base_dir: str | os.PathLike | None = None) -> Path:
    """Build the report (arguments as for :func:`harness.report.markdown.write_report`) and
    write ``out_dir/report.html`` with its figures inline; returns its path."""
    return write_html(build_report(run_dirs_or_records, out_dir, title=title, base_dir=base_dir))


def write_reports(run_dirs_or_records, out_dir: str | os.PathLike, *, title: str = "ConceptFusion harness report",
                  base_dir: str | os.PathLike | None = None) -> tuple[Path, Path]:
    """Build the report once and write both ``report.md`` (with its PNG files) and
    ``report.html``; returns (Markdown path, HTML path)."""
    doc = build_report(run_dirs_or_records, out_dir, title=title, base_dir=base_dir)
    return write_markdown(doc), write_html(doc)
