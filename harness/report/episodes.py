"""One row per episode, failures first, linking each episode's replay video and map.

The table goes to the HTML report only (a Markdown report with hundreds of rows reads badly).
Replays are found by name beside the run (:func:`harness.report.paths.replay_stem`):
``RUN/replays/<stem>.mp4`` (else ``.gif``) and the final map ``RUN/replays/<stem>.map.npz``; links
are relative to the report folder, so the videos stay beside the report instead of inside it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from urllib.parse import quote

from harness.report.document import Cell, Table
from harness.report.paths import MAP_SUFFIX, REPLAYS_DIR, VIDEO_SUFFIXES, replay_stem
from harness.report.stats import DEFAULT_METRICS, metric_value
from harness.runner.results import agent_label

__all__ = ["episode_table", "find_replay"]

_MAX_METRICS = 4
_ERROR_CHARS = 120


def find_replay(record: dict, run_dir: str | os.PathLike | None) -> tuple[Path | None, Path | None]:
    """(video, map) of an episode's replay files under ``run_dir/replays``, each None when absent.

    ``run_dir`` None (records passed without a folder) finds nothing.
    """
    if run_dir is None:
        return None, None
    folder = Path(run_dir) / REPLAYS_DIR
    stem = replay_stem(record)
    video = next((folder / f"{stem}{s}" for s in VIDEO_SUFFIXES if (folder / f"{stem}{s}").is_file()), None)
    map_path = folder / f"{stem}{MAP_SUFFIX}"
    return video, (map_path if map_path.is_file() else None)


def _href(target: Path, out_dir: Path) -> str:
    rel = os.path.relpath(Path(target).resolve(), Path(out_dir).resolve())
    return quote(rel.replace(os.sep, "/"))


def _outcome(record: dict) -> tuple[int, str]:
    """(order: 0 crashed or timed out, 1 unsuccessful or unscored, 2 successful; text)."""
    if record["status"] != "ok":
        return 0, record["status"]
    success = metric_value(record, "success")
    if success is None:
        return 1, "ok"
    return (2, "success") if success else (1, "miss")


def _number(value) -> Cell:
    if value is None:
        return Cell("-", sort=math.nan)
    if isinstance(value, bool):
        return Cell("yes" if value else "no", sort=float(value))
    return Cell(f"{value:.2f}" if abs(value) < 1000 else f"{value:.0f}", sort=value)


def episode_table(run_items, suite: str, out_dir: str | os.PathLike, *, show_run: bool = False) -> Table:
    """The episodes of ``suite``: failed and timed-out first, then misses, then successes.

    ``run_items``: (record, run folder or None, run label) triples. Columns: run (with
    ``show_run``), agent, encoder, episode, seed, outcome, success and up to four more metrics,
    wall time, error, replay and map links (when the files exist).
    """
    recs = [(r, base, label) for r, base, label in run_items if r["suite"] == suite]
    seen = {m for r, _, _ in recs for m in (r.get("metrics") or {})}
    metrics = ([m for m in DEFAULT_METRICS if m in seen] + sorted(seen - set(DEFAULT_METRICS)))[:_MAX_METRICS + 1]
    head = (*(("run",) if show_run else ()), "agent", "encoder", "episode", "seed", "outcome", *metrics,
            "s", "error", "replay", "map")
    out = Path(out_dir)
    rows = []
    for r, base, label in recs:
        order, text = _outcome(r)
        video, map_path = find_replay(r, base)
        error = r.get("error") or ""
        wall = (r.get("timings") or {}).get("wall_s")
        rows.append(((order, label, agent_label(r["agent"], r.get("agent_kwargs")), r["episode_id"], r["seed"]), (
            *((label,) if show_run else ()), agent_label(r["agent"], r.get("agent_kwargs")), r["encoder"],
            r["episode_id"], Cell(str(r["seed"]), sort=r["seed"]), Cell(text, sort=order),
            *(_number(metric_value(r, m)) for m in metrics),
            Cell(f"{wall:.1f}", sort=wall) if isinstance(wall, (int, float)) else Cell("-", sort=math.nan),
            Cell(error if len(error) <= _ERROR_CHARS else error[:_ERROR_CHARS - 3] + "...", title=error or None),
            Cell("video", href=_href(video, out)) if video else Cell("-"),
            Cell("map", href=_href(map_path, out), title=f"cfharness view {map_path} --encoder {r['encoder']}")
            if map_path else Cell("-"),
        )))
    rows.sort(key=lambda kr: kr[0])
    failed = sum(kr[0][0] < 2 for kr in rows)
    return Table(head, [row for _, row in rows], markdown=False, name=f"episodes-{suite}",
                 caption=f"Episodes of {suite}: {len(rows)}, {failed} not successful (listed first)",
                 row_kinds=tuple(("failed", "miss", "success")[key[0]] for key, _ in rows))
