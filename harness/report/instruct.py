"""Does a language planner do better when it is told what the map holds? The ``instruct-v2`` table.

The paper's planner-in-the-loop comparison on instruction episodes (needs, rooms, relations):
``map-planner`` (the planner told the map's rooms and objects, asking it spatial questions)
against ``generic-planner`` (the same planner and navigator, the instruction alone), with the
privileged ``oracle-searcher`` as the upper bound. :func:`instruct_rows` gives, per perception
and agent, the success rate with its Wilson interval overall and per instruction kind, SPL, and
for ``map-planner`` the paired difference to ``generic-planner`` on the same episodes (bootstrap
interval, exact McNemar p) and the share of its CPU time its planner calls and its map listings
took.

``cfharness develop instruct RUN... --write`` measures it once for the README: it keeps the
stripped records in :data:`RECORDS_FILE` and writes the README's table between its markers; a
test recomputes the table from that file.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from conceptfusion.errors import HarnessError
from harness.report.headline import read_kept_records, replace_between_markers
from harness.report.stats import bootstrap_ci, mcnemar_exact, metric_value, wilson_interval
from harness.runner.results import latest_records, load_results

__all__ = ["SUITES", "KINDS", "MAP_AGENT", "GENERIC_AGENT", "RECORDS_FILE", "InstructRow", "instruct_rows", "instruct_table",
           "keep_record", "readme_with_table", "read_kept_records", "main"]

SUITES = ("instruct-v2",)
"""The suites the table reads."""
KINDS = ("need", "room", "relation")
MAP_AGENT, GENERIC_AGENT = "map-planner", "generic-planner"
RECORDS_FILE = Path(__file__).resolve().parents[1] / "data" / "instruct" / "records.jsonl"
README_START = "<!-- instruct table: cfharness develop instruct RUN... --write -->"
README_END = "<!-- end of the instruct table -->"


@dataclass(frozen=True)
class InstructRow:
    """One agent under one perception on the instruction episodes."""

    suite: str
    agent: str
    encoder: str
    privileged: bool
    n: int
    successes: int
    by_kind: dict
    """Kind -> (successes, episodes)."""
    spl: float
    diff: tuple[float, float, float, float, int] | None = None
    """``map-planner`` only: (difference to ``generic-planner``, CI low, CI high, McNemar p, paired episodes)."""
    planner_share: float | None = None
    """Planner calls' share of the episodes' CPU time (agent plus environment), summed over episodes."""
    listing_share: float | None = None
    """The map listings' share of the same."""


def _key(r: dict) -> tuple:
    return r["episode_id"], r["seed"]


def instruct_rows(records: list[dict]) -> list[InstructRow]:
    """Rows for every (suite, encoder, agent) of :data:`SUITES` in ``records`` (newest record per episode).

    Raises:
        HarnessError: no record of an instruction suite.
    """
    records = [r for r in latest_records(records) if r["suite"] in SUITES and r["status"] in ("ok", "timeout", "failed")]
    if not records:
        raise HarnessError(f"instruct: expected records of {', '.join(SUITES)}; found none")
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r["suite"], r["encoder"], r["agent"]), []).append(r)
    order = {MAP_AGENT: 0, GENERIC_AGENT: 1}
    out = []
    for (suite, enc, agent), recs in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1] == "none", kv[0][1],
                                                                            order.get(kv[0][2], 2), kv[0][2])):
        ok = [bool(metric_value(r, "success")) for r in recs]
        by_kind = {}
        for kind in KINDS:
            flags = [o for r, o in zip(recs, ok) if (r.get("extras") or {}).get("instruction_kind") == kind]
            by_kind[kind] = (sum(flags), len(flags))
        spl = float(np.mean([float((r.get("metrics") or {}).get("spl", 0.0)) for r in recs]))
        diff = shares = None
        if agent == MAP_AGENT and (suite, enc, GENERIC_AGENT) in groups:
            a = {_key(r): bool(metric_value(r, "success")) for r in groups[(suite, enc, GENERIC_AGENT)]}
            b = {_key(r): o for r, o in zip(recs, ok)}
            keys = sorted(set(a) & set(b))
            if keys:
                xa, xb = np.array([a[k] for k in keys], float), np.array([b[k] for k in keys], float)
                lo, hi = bootstrap_ci(xb - xa)
                p = mcnemar_exact(int(((xb == 1) & (xa == 0)).sum()), int(((xa == 1) & (xb == 0)).sum()))
                diff = (float(xb.mean() - xa.mean()), float(lo), float(hi), float(p), len(keys))
            shares = _shares(recs)
        privileged = any((r.get("extras") or {}).get("privileged") for r in recs)
        out.append(InstructRow(suite, agent, enc, privileged, len(recs), sum(ok), by_kind, spl, diff,
                               *(shares if shares else (None, None))))
    return out


def _shares(recs: list[dict]) -> tuple[float, float] | None:
    """(planner, listing) share of the episodes' CPU time, from the records' timings and planner extras."""
    total = planner = listing = 0.0
    for r in recs:
        t = r.get("timings") or {}
        info = (r.get("extras") or {}).get("planner") or {}
        if "agent_s" not in t or "planner_s" not in info:
            return None
        total += float(t["agent_s"]) + float(t.get("env_s", 0.0))
        planner += float(info["planner_s"])
        listing += float(info.get("context_s", 0.0))
    return (planner / total, listing / total) if total > 0 else None


def _rate(k: int, n: int) -> str:
    if not n:
        return "-"
    lo, hi = wilson_interval(k, n)
    return f"{k}/{n} = {k / n:.2f} [{lo:.2f}, {hi:.2f}]"


def instruct_table(rows: list[InstructRow]) -> str:
    """The rows as a Markdown table."""
    head = ["perception", "agent", "success [95% CI]", *(f"{k}" for k in KINDS), "SPL",
            f"{MAP_AGENT} - {GENERIC_AGENT} [95% CI]", "McNemar p", "planner / listing CPU"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        enc = f"{r.encoder} (privileged)" if r.privileged and r.encoder != "none" else r.encoder
        agent = f"{r.agent} (privileged)" if r.privileged and r.encoder == "none" else r.agent
        kinds = [f"{k}/{n}" if n else "-" for k, n in (r.by_kind[kind] for kind in KINDS)]
        d = f"{r.diff[0]:+.2f} [{r.diff[1]:+.2f}, {r.diff[2]:+.2f}] (n={r.diff[4]})" if r.diff else ""
        p = f"{r.diff[3]:.2g}" if r.diff else ""
        cpu = f"{r.planner_share:.1%} / {r.listing_share:.1%}" if r.planner_share is not None else ""
        lines.append(f"| {enc} | {agent} | {_rate(r.successes, r.n)} | " + " | ".join(kinds)
                     + f" | {r.spl:.2f} | {d} | {p} | {cpu} |")
    return "\n".join(lines)


def keep_record(r: dict) -> dict:
    """What the kept records hold of a record: identity, success, SPL, the instruction kind, timings
    and the planner's times (not its calls)."""
    extras = r.get("extras") or {}
    planner = extras.get("planner") or {}
    keep_extras = {k: extras[k] for k in ("instruction_kind", "privileged", "stop_reason") if k in extras}
    if planner:
        keep_extras["planner"] = {k: planner[k] for k in ("backend", "map_context", "calls", "planner_s", "context_s", "failure")
                                  if k in planner}
    metrics = {k: v for k, v in (r.get("metrics") or {}).items() if k in ("success", "spl")}
    timings = {k: v for k, v in (r.get("timings") or {}).items() if k in ("agent_s", "env_s")}
    return {"suite": r["suite"], "agent": r["agent"], "encoder": r["encoder"], "episode_id": r["episode_id"], "seed": r["seed"],
            "status": r["status"], "metrics": metrics, "timings": timings, "extras": keep_extras}


def readme_with_table(readme: str, table: str) -> str:
    """``readme`` with the text between :data:`README_START` and :data:`README_END` replaced by ``table``."""
    return replace_between_markers(readme, README_START, README_END, table, "instruct table")


def main(argv: list[str] | None = None) -> int:
    from harness.report.headline import write_measurement

    p = argparse.ArgumentParser(prog="cfharness develop instruct", description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="run folders of instruct-v2 runs")
    p.add_argument("--write", action="store_true", help=f"keep the records in {RECORDS_FILE} and write the README's table")
    args = p.parse_args(argv)
    try:
        records = [keep_record(r) for run in args.runs for r in load_results(Path(run) / "results.jsonl") if r["suite"] in SUITES]
        table = instruct_table(instruct_rows(records))
    except (HarnessError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(table)
    if args.write:
        return write_measurement(RECORDS_FILE, latest_records(records), table, README_START, README_END, "instruct table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
