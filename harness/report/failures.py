"""Why a suite's episodes failed: one page per suite (``failures-<suite>.html`` beside
``report.html``) with the failures grouped by cause, and a count table for the suite's section.

A failure is a crash, a timeout, or an ``ok`` episode with ``success`` False
(:func:`harness.report.causes.is_failure`); its cause is
:func:`harness.report.causes.failure_cause`. Each group on the page gives its count, per agent,
and its episodes: goal, category, agent, what the metrics say, the replay video (inline, loaded
only when opened) and the command that opens the final map in the viewer.
"""

from __future__ import annotations

import html
import re
from collections import Counter
from pathlib import Path

from conceptfusion.io_utils import atomic_write_text
from harness.report.causes import CAUSES, RECORDED_CAUSES, cause_text, failure_cause, goal_text, success_radius
from harness.report.document import Cell, Heading, Paragraph, Table
from harness.report.links import ReportLinks
from harness.report.widgets import WIDGET_CSS, WIDGET_JS, command_html
from harness.runner.results import agent_label

__all__ = ["failures_file", "failure_groups", "failure_section", "render_failure_page"]


def failures_file(suite: str) -> str:
    """The failure page's file name for ``suite`` (characters outside ``[A-Za-z0-9._-]`` become ``-``)."""
    return "failures-" + (re.sub(r"[^A-Za-z0-9._-]+", "-", str(suite)).strip("-.") or "suite") + ".html"


def failure_groups(run_items, suite: str) -> dict[str, list[tuple[dict, Path | None, str]]]:
    """Cause label -> the failed (record, run folder, run label) of ``suite``, in :data:`CAUSES`
    order (unlisted recorded causes last), each group by agent, episode and seed."""
    groups: dict[str, list] = {}
    for item in run_items:
        if item[0]["suite"] != suite:
            continue
        cause = failure_cause(item[0])
        if cause is not None:
            groups.setdefault(cause, []).append(item)
    order = list(CAUSES)
    ranked = sorted(groups, key=lambda c: (order.index(c) if c in order else len(order), c))
    return {c: sorted(groups[c], key=lambda it: (it[2], _agent(it[0]), str(it[0]["episode_id"]), it[0]["seed"]))
            for c in ranked}


def _agent(record: dict) -> str:
    return agent_label(record["agent"], record.get("agent_kwargs"))


def _anchor(cause: str) -> str:
    return "cause-" + re.sub(r"[^a-z0-9]+", "-", cause.lower()).strip("-")


def _derived(records) -> bool:
    return any(not isinstance((r.get("extras") or {}).get("stop_reason"), str) and r.get("status") == "ok"
               for r in records)


def failure_section(run_items, suite: str, links: ReportLinks) -> list:
    """Write ``failures-<suite>.html`` into ``links.out_dir`` and return the suite section's
    blocks: a heading, a line on where causes come from, and a table of failures per cause and
    agent whose counts link to their group on the page. Empty (and no page) when nothing failed."""
    groups = failure_groups(run_items, suite)
    if not groups:
        return []
    page = failures_file(suite)
    atomic_write_text(Path(links.out_dir) / page, render_failure_page(suite, groups, links,
                                                                       several_runs=len({it[2] for it in run_items}) > 1))
    agents = sorted({_agent(r) for items in groups.values() for r, _, _ in items})
    head = ("cause", "meaning", "failures", *agents)
    body = []
    for cause, items in groups.items():
        per_agent = Counter(_agent(r) for r, _, _ in items)
        href = f"{page}#{_anchor(cause)}"
        body.append((Cell(cause, href=href), cause_text(cause), Cell(str(len(items)), sort=len(items), href=href),
                     *(Cell(str(per_agent[a]), sort=per_agent[a]) if per_agent[a] else Cell("-", sort=0) for a in agents)))
    every = [r for items in groups.values() for r, _, _ in items]
    where = ("each episode's recorded cause (extras.stop_reason)" if not _derived(every) else
             "the recorded cause (extras.stop_reason) where there is one; records without it get a coarse cause "
             "derived from their status and metrics (marked derived)")
    return [Heading(3, "Why episodes failed"),
            Paragraph(f"{len(every)} failed episodes by cause: {where}. Each cause links to its episodes, with their "
                      f"goals, replay videos and maps, on `{page}`."),
            Table(head, body, name=f"failures-{suite}")]


def _detail(record: dict) -> str:
    """What the record's metrics say about how it ended, in words."""
    m = record.get("metrics") or {}
    parts = []
    d = m.get("distance_to_goal")
    if isinstance(d, (int, float)) and not isinstance(d, bool):
        radius, recorded = success_radius(record)
        parts.append(f"ended {d:.2f} m from the goal (success within {radius:g} m"
                     f"{'' if recorded else ', the default'})")
    if isinstance(m.get("goals_reached"), int) and isinstance(m.get("chain_length"), int):
        parts.append(f"reached {m['goals_reached']} of {m['chain_length']} goals")
    for key, word in (("steps", "steps"), ("collisions", "collisions")):
        if isinstance(m.get(key), (int, float)) and not isinstance(m.get(key), bool):
            parts.append(f"{m[key]:g} {word}")
    if record.get("error"):
        parts.append(str(record["error"]))
    return "; ".join(parts) or "-"


_PAGE_CSS = """
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: #1d2430; margin: 0 auto;
       max-width: 1280px; padding: 16px 24px 48px; }
h1 { font-size: 22px; margin: 8px 0 4px; } h2 { font-size: 17px; margin: 28px 0 6px; border-bottom: 1px solid #d8dde6; }
a { color: #2f6fdb; } .muted { color: #5b6575; }
table { border-collapse: collapse; font-size: 13px; margin: 6px 0 10px; }
th, td { border: 1px solid #d8dde6; padding: 4px 8px; text-align: left; vertical-align: top; }
th { background: #eef1f6; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.goal { max-width: 22em; } td.detail { max-width: 26em; font-size: 12.5px; } td.id { white-space: nowrap; }
details.play > summary { cursor: pointer; color: #2f6fdb; }
details.play video { display: block; width: 360px; max-width: 40vw; margin-top: 4px; background: #111; }
"""

_PAGE_JS = r"""
document.querySelectorAll('details.play').forEach(function (d) {
  d.addEventListener('toggle', function () {
    var v = d.querySelector('video');
    if (v && d.open) { v.play().catch(function () {}); } else if (v) { v.pause(); }
  });
});
"""


def _video_html(replay) -> str:
    if replay.video:
        src = html.escape(replay.video)
        out = (f'<details class="play"><summary>play</summary><video controls preload="none" src="{src}"></video>'
               f'</details><a href="{src}">file</a>')
    else:
        out = "-" if not replay.video_note else "missing"
    if replay.video_note:
        out += f'<span class="cf-note">{html.escape(replay.video_note)}</span>'
    return out


def _map_html(replay) -> str:
    if replay.command is None:
        return "-"
    link = f'<a href="{html.escape(replay.map)}">map file</a> ' if replay.map else ""
    return link + command_html(replay.command, replay.map_note)


def render_failure_page(suite: str, groups: dict, links: ReportLinks, *, several_runs: bool = False) -> str:
    """The HTML text of ``suite``'s failure page (``groups`` as :func:`failure_groups` returns)."""
    total = sum(len(v) for v in groups.values())
    esc = html.escape
    summary_rows = "".join(
        f'<tr><td><a href="#{_anchor(c)}">{esc(c)}</a></td><td>{esc(cause_text(c))}</td>'
        f'<td class="num">{len(items)}</td><td>{esc(", ".join(f"{a} {n}" for a, n in sorted(Counter(_agent(r) for r, _, _ in items).items())))}</td></tr>'
        for c, items in groups.items())
    sections = []
    for cause, items in groups.items():
        rows = []
        for r, base, label in items:
            replay = links.replay(r, base)
            goal = goal_text(r)
            recorded = isinstance((r.get("extras") or {}).get("stop_reason"), str) or r.get("status") != "ok"
            goal_cell = esc(goal) if goal else '<span class="muted">not recorded</span>'
            derived = "" if recorded else ' <span class="muted">(cause derived)</span>'
            rows.append(
                "<tr>" + (f"<td>{esc(label)}</td>" if several_runs else "")
                + f'<td class="id">{esc(_agent(r))}<br><span class="muted">{esc(str(r["encoder"]))}</span></td>'
                f'<td class="id">{esc(str(r["episode_id"]))}<br><span class="muted">seed {esc(str(r["seed"]))}</span></td>'
                f'<td class="goal">{goal_cell}</td><td>{esc(str(r.get("category") or "-"))}</td>'
                f'<td class="detail">{esc(_detail(r))}{derived}</td>'
                f"<td>{_video_html(replay)}</td><td>{_map_html(replay)}</td></tr>")
        by_agent = ", ".join(f"{a} {n}" for a, n in sorted(Counter(_agent(r) for r, _, _ in items).items()))
        sections.append(
            f'<h2 id="{_anchor(cause)}">{esc(cause)}: {len(items)} <span class="muted">({esc(by_agent)})</span></h2>'
            f"<p>{esc(cause_text(cause))}.</p><table><thead><tr>" + ("<th>run</th>" if several_runs else "")
            + "<th>agent</th><th>episode</th><th>goal</th><th>category</th><th>how it ended</th><th>video</th>"
              "<th>map</th></tr></thead><tbody>" + "\n".join(rows) + "</tbody></table>")
    origin = ("Causes are the episodes' recorded stop_reason (one of " + ", ".join(RECORDED_CAUSES)
              + "), or, for records without it, derived from the status and metrics.")
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>Failures of {esc(suite)}</title><style>{_PAGE_CSS}{WIDGET_CSS}</style></head><body>",
        '<p class="muted"><a href="report.html">back to the report</a></p>',
        f"<h1>Why episodes of <code>{esc(suite)}</code> failed: {total} failures</h1>",
        f'<p class="muted">{esc(origin)} A map opens in the viewer with the command shown (a static page cannot '
        "start it).</p>",
        "<table><thead><tr><th>cause</th><th>meaning</th><th>failures</th><th>by agent</th></tr></thead><tbody>"
        + summary_rows + "</tbody></table>",
        *sections,
        f"<script>{_PAGE_JS}{WIDGET_JS}</script>", "</body></html>", "",
    ])
