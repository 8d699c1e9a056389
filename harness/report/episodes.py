"""One row per episode, failures first, with its goal, why it failed, and its replay video and map.

The table goes to the HTML report only (a Markdown report with hundreds of rows reads badly).
Replays are found by name beside the run (:func:`harness.report.paths.replay_stem`):
``RUN/replays/<stem>.mp4`` (else ``.gif``) and the final map ``RUN/replays/<stem>.map.npz``, linked
as :class:`~harness.report.links.ReportLinks` says (relative to the report folder, or copies
inside a bundle); a map is shown as the command that opens it in the viewer.

Agent suites (a ``success`` metric) mark each row success, miss, or the status of a crash or
timeout, with the cause of a failure (:func:`harness.report.causes.failure_cause`). Map suites
have no success: their rows give the suite's headline metric
(:func:`harness.report.cards.headline_metric`) instead.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from harness.report.cards import headline_metric
from harness.report.causes import cause_text, failure_cause, goal_text
from harness.report.document import Cell, Table
from harness.report.links import ReportLinks
from harness.report.stats import metric_value
from harness.runner.results import agent_label

__all__ = ["episode_table"]

_PREFERRED = ("success", "spl", "distance_to_goal", "steps", "collisions", "goals_reached")
_MAX_METRICS = 5
_ERROR_CHARS = 120

def _outcome(record: dict, headline: str | None) -> tuple[int, str, str]:
    """(order: 0 crashed or timed out, 1 miss, 2 success or unscored; text; row kind)."""
    if record["status"] != "ok":
        return 0, record["status"], "failed"
    if headline == "success":
        success = metric_value(record, "success")
        if success is None:
            return 1, "unscored", "miss"
        return (2, "success", "success") if success else (1, "miss", "miss")
    value = metric_value(record, headline) if headline else None
    if value is None:
        return 2, f"{headline}: -" if headline else "ok", ""
    return 2, f"{headline} {float(value):.2f}", ""


def _number(value, integer: bool = False) -> Cell:
    if value is None:
        return Cell("-", sort=math.nan)
    if isinstance(value, bool):
        return Cell("yes" if value else "no", sort=float(value))
    if integer:
        return Cell(f"{value:.0f}", sort=value)
    return Cell(f"{value:.2f}" if abs(value) < 1000 else f"{value:.0f}", sort=value)


def _text(cell) -> str:
    return cell.text if isinstance(cell, Cell) else str(cell)


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _metric_columns(recs, headline: str | None) -> list[str]:
    seen = {m for r in recs for m in (r.get("metrics") or {})}
    first = [m for m in (headline, *_PREFERRED) if m and m in seen]
    first = list(dict.fromkeys(first))
    return (first + sorted(seen - set(first)))[:_MAX_METRICS]


def _video_cell(links) -> Cell:
    if links.video:
        return Cell("video", href=links.video, note=links.video_note or None)
    if links.video_note:
        return Cell("missing", title=links.video_note, note=links.video_note)
    return Cell("-")


def _map_cell(links) -> Cell:
    if links.command is None:
        return Cell("-")
    return Cell("map" if links.map else "map (not here)", href=links.map, command=links.command,
                note=links.map_note or None)


def episode_table(run_items, suite: str, out_dir: str | os.PathLike, *, show_run: bool = False,
                  links: ReportLinks | None = None) -> Table:
    """The episodes of ``suite``: crashed and timed-out first, then misses, then the rest.

    ``run_items``: (record, run folder or None, run label) triples. Columns: run (with
    ``show_run``), agent, encoder, episode, seed, outcome (success / miss / the status, or a map
    suite's headline metric), cause (of a failure), goal (``extras.goal``), category, up to five
    metrics, wall time, error, replay and map (``links``; default: relative to ``out_dir``). A map
    suite leaves out cause, goal and category when none of its rows has one.
    """
    links = links or ReportLinks(Path(out_dir))
    recs = [(r, base, label) for r, base, label in run_items if r["suite"] == suite]
    headline = headline_metric([r for r, _, _ in recs], suite)
    metrics = _metric_columns([r for r, _, _ in recs], headline)
    head = (*(("run",) if show_run else ()), "agent", "encoder", "episode", "seed", "outcome", "cause", "goal",
            "category", *metrics, "s", "error", "replay", "map")
    rows = []
    for r, base, label in recs:
        order, text, kind = _outcome(r, headline)
        cause = failure_cause(r) if headline == "success" or r["status"] != "ok" else None
        replay = links.replay(r, base)
        error = r.get("error") or ""
        wall = (r.get("timings") or {}).get("wall_s")
        goal = goal_text(r)
        agent = agent_label(r["agent"], r.get("agent_kwargs"))
        rows.append(((order, label, agent, r["episode_id"], r["seed"]), kind, (
            *((label,) if show_run else ()), agent, r["encoder"], r["episode_id"], Cell(str(r["seed"]), sort=r["seed"]),
            Cell(text, sort=order),
            Cell(cause, title=cause_text(cause)) if cause else Cell("-"),
            Cell(goal) if goal else Cell("-", title="the record holds no goal text (extras.goal)"),
            r.get("category") or "-",
            *(_number(metric_value(r, m), _is_int((r.get("metrics") or {}).get(m))) for m in metrics),
            Cell(f"{wall:.1f}", sort=wall) if isinstance(wall, (int, float)) else Cell("-", sort=math.nan),
            Cell(error if len(error) <= _ERROR_CHARS else error[:_ERROR_CHARS - 3] + "...", title=error or None),
            _video_cell(replay), _map_cell(replay),
        )))
    rows.sort(key=lambda kr: kr[0])
    if headline != "success":  # a map suite: leave out the columns none of its rows fills
        empty = {h for i, h in enumerate(head) if h in ("cause", "goal", "category")
                 and all(_text(row[i]) == "-" for _, _, row in rows)}
        keep = [i for i, h in enumerate(head) if h not in empty]
        head = tuple(head[i] for i in keep)
        rows = [(key, kind, tuple(row[i] for i in keep)) for key, kind, row in rows]
    if headline == "success":
        failed = sum(kr[0][0] < 2 for kr in rows)
        caption = f"Episodes of {suite}: {len(rows)}, {failed} not successful (listed first)"
    else:
        crashed = sum(kr[0][0] == 0 for kr in rows)
        caption = (f"Episodes of {suite}: {len(rows)}, no success metric (a map suite): each row gives "
                   f"{headline or 'its status'}; {crashed} crashed or timed out (listed first)")
    return Table(head, [row for _, _, row in rows], markdown=False, name=f"episodes-{suite}", caption=caption,
                 row_kinds=tuple(kind for _, kind, _ in rows))
