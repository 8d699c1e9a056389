"""The headline figures: measured once on the sealed test set, kept with the records they come from.

``python -m harness.report.headline RUN... --write`` reads the records of run folders over the
sealed suites (``rearrange-v2``, ``search-v2``, ``chain-v2``, ``fetch-v2``, each with ``--limit``
of its whole file), refuses records of any other episode file, and writes:

- ``harness/data/sealed/records.jsonl``: the records, stripped to what the figures need
  (suite, agent, encoder, episode, seed, status, success and the chain positions, the goal's split
  group and the ``twin_of`` / ``uses_map`` / ``privileged`` marks);
- ``harness/data/sealed/measured.json``: the figures (:func:`headline`) with the commit that
  measured them and the sealed manifest's SHA-256;
- the README's headline table, between its markers (:func:`readme_with_tables`).

Figures, per suite and encoder: every agent's success with its 95% Wilson interval; each map
agent minus its matched twin, paired per episode (bootstrap interval, exact McNemar); the chain
suite's success per position (``reached_k``: the first k goals in a row); and, per agent, success
by the goal's split group (seen, held-out instance, held-out category). The README's headline
table is :func:`headline_table`; :func:`positions_table` and :func:`agents_table` go on the
generated results page (:mod:`harness.report.results_page`); a test recomputes the file from the
records.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

from conceptfusion.errors import HarnessError
from conceptfusion.io_utils import atomic_write_text
from conceptfusion.strict_json import loads_strict
from harness.report.stats import metric_value, paired_comparison, wilson_interval
from harness.runner.results import latest_records, load_results
from sim_envs.scenes.sealed import MANIFEST_NAME, SEALED_FOLDER

__all__ = ["SEALED_SUITES", "DATA_DIR", "RECORDS_FILE", "MEASURED_FILE", "strip_record", "headline", "headline_table", "agents_table",
           "positions_table", "readme_with_tables", "replace_between_markers", "read_kept_records", "write_kept_records", "main"]

SEALED_SUITES = {"rearrange-v2": 160, "search-v2": 150, "chain-v2": 30, "fetch-v2": 30}
"""The suites measured on the sealed set, with their whole size."""
DATA_DIR = Path(__file__).resolve().parents[1] / "data" / "sealed"
RECORDS_FILE = DATA_DIR / "records.jsonl"
MEASURED_FILE = DATA_DIR / "measured.json"

_KEEP_EXTRAS = ("twin_of", "uses_map", "privileged", "goal_split")


def strip_record(r: dict) -> dict:
    """A record with what the headline figures need only."""
    metrics = {k: v for k, v in (r.get("metrics") or {}).items() if k == "success" or k.startswith("reached_")}
    extras = {k: v for k, v in (r.get("extras") or {}).items() if k in _KEEP_EXTRAS}
    return {"suite": r["suite"], "agent": r["agent"], "encoder": r["encoder"], "episode_id": r["episode_id"],
            "seed": r["seed"], "status": r["status"], "metrics": metrics, "extras": extras}


def _rate(values: list[bool]) -> dict:
    k, n = sum(values), len(values)
    lo, hi = wilson_interval(k, n) if n else (float("nan"), float("nan"))
    return {"successes": k, "n": n, "rate": round(k / n, 4) if n else None, "ci": [round(lo, 4), round(hi, 4)]}


def headline(records: list[dict]) -> dict:
    """The headline figures of sealed-suite records (see the module docstring).

    Raises:
        HarnessError: a record of another suite, or a suite whose agents ran different episodes
            than its size says (a slice is not a headline).
    """
    records = latest_records(records)
    out: dict = {}
    for r in records:
        if r["suite"] not in SEALED_SUITES:
            raise HarnessError(f"headline: record of suite {r['suite']!r}; expected only {', '.join(SEALED_SUITES)}")
    for suite, size in SEALED_SUITES.items():
        mine = [r for r in records if r["suite"] == suite]
        if not mine:
            continue
        by_enc: dict = {}
        for enc in sorted({r["encoder"] for r in mine}):
            recs = [r for r in mine if r["encoder"] == enc]
            agents: dict = {}
            for agent in sorted({r["agent"] for r in recs}):
                ra = [r for r in recs if r["agent"] == agent]
                if len(ra) != size:
                    raise HarnessError(f"headline: {suite} {agent} ({enc}) has {len(ra)} records; the headline needs all {size}")
                flags = [bool(metric_value(r, "success")) for r in ra]
                entry = {"success": _rate(flags), "privileged": any((r.get("extras") or {}).get("privileged") for r in ra)}
                twin_of = {(r.get("extras") or {}).get("twin_of") for r in ra} - {None}
                if twin_of:
                    entry["twin_of"] = sorted(twin_of)[0]
                groups = sorted({(r.get("extras") or {}).get("goal_split") for r in ra} - {None})
                if groups:
                    entry["by_group"] = {g: _rate([bool(metric_value(r, "success")) for r in ra
                                                   if (r.get("extras") or {}).get("goal_split") == g]) for g in groups}
                positions = sorted({int(k.split("_")[1]) for r in ra for k in r["metrics"] if k.startswith("reached_")})
                if positions:
                    entry["positions"] = {str(k): _rate([bool(r["metrics"][f"reached_{k}"]) for r in ra if f"reached_{k}" in r["metrics"]])
                                          for k in positions}
                agents[agent] = entry
            twins = {}
            for agent, entry in agents.items():
                base = entry.get("twin_of")
                if base in agents:
                    res = paired_comparison(recs, base, agent, "success", suite=suite, encoder=enc)
                    twins[f"{base} - {agent}"] = {
                        "diff": round(res.mean_diff, 4), "ci": [round(res.ci_low, 4), round(res.ci_high, 4)],
                        "map_only": res.a_only, "twin_only": res.b_only, "p": float(f"{res.p_value:.3g}"), "pairs": res.n_pairs}
            by_enc[enc] = {"agents": agents, "twins": twins}
        out[suite] = by_enc
    return out


def headline_table(measured: dict) -> str:
    """The README's headline table (Markdown) of a measured file: per suite and encoder, the map
    agent, its twin and their paired difference."""
    rows = ["| suite | perception | map agent | matched twin | map - twin [95% CI] | McNemar p | n |",
            "|---|---|---|---|---|---|---|"]
    for suite, by_enc in _in_order(measured["figures"]):
        for enc, fig in by_enc.items():
            for pair, d in fig["twins"].items():
                base, twin = pair.split(" - ")
                a, b = fig["agents"][base]["success"], fig["agents"][twin]["success"]
                priv = " (privileged)" if fig["agents"][base]["privileged"] else ""
                rows.append(f"| `{suite}` | {enc}{priv} | {base} {a['successes']}/{a['n']} | {twin} {b['successes']}/{b['n']} "
                            f"| {d['diff']:+.2f} [{d['ci'][0]:+.2f}, {d['ci'][1]:+.2f}] | {d['p']:.2g} | {d['pairs']} |")
    return "\n".join(rows)


def _in_order(figures: dict) -> list[tuple[str, dict]]:
    """(suite, figures by encoder) in :data:`SEALED_SUITES` order, whatever order a file keeps."""
    return [(suite, figures[suite]) for suite in SEALED_SUITES if suite in figures]


def _cell(s: dict) -> str:
    return f"{s['successes']}/{s['n']} = {s['rate']:.2f} [{s['ci'][0]:.2f}, {s['ci'][1]:.2f}]"


def agents_table(measured: dict) -> str:
    """Every agent's success per suite and encoder (map agents, twins, weak and random references
    and the privileged oracles, marked), Markdown."""
    rows = ["| suite | agent | perception | success [95% CI] |", "|---|---|---|---|"]
    for suite, by_enc in _in_order(measured["figures"]):
        for enc, fig in by_enc.items():
            for agent, entry in fig["agents"].items():
                label = "ground truth (privileged)" if agent.startswith("oracle-") else "none" if agent.startswith("random-") else enc
                if entry["privileged"] and not agent.startswith("oracle-"):
                    label += " (privileged)"
                rows.append(f"| `{suite}` | {agent} | {label} | {_cell(entry['success'])} |")
    return "\n".join(rows)


def positions_table(measured: dict) -> str:
    """Multi-goal success per position in the chain (the first k goals reached in a row), Markdown."""
    rows = ["| suite | agent | perception | 1 goal | 2 in a row | 3 in a row | 4 in a row |", "|---|---|---|---|---|---|---|"]
    for suite, by_enc in _in_order(measured["figures"]):
        for enc, fig in by_enc.items():
            for agent, entry in fig["agents"].items():
                if "positions" not in entry or agent.startswith(("oracle-", "random-")):
                    continue
                cells = [f"{p['successes']}/{p['n']} = {p['rate']:.2f}" for _, p in sorted(entry["positions"].items(), key=lambda kv: int(kv[0]))]
                priv = " (privileged)" if entry["privileged"] else ""
                rows.append(f"| `{suite}` | {agent} | {enc}{priv} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


README_START = "<!-- headline tables: python -m harness.report.headline RUN... --write -->"
README_END = "<!-- end of the headline tables -->"


def replace_between_markers(text: str, start: str, end: str, body: str, what: str) -> str:
    """``text`` with what lies between the lines ``start`` and ``end`` replaced by ``body``: how a
    generated table is kept in the README.

    Raises:
        HarnessError: the text lacks either marker (``what`` names the table in the message).
    """
    try:
        head, rest = text.split(start, 1)
        _, tail = rest.split(end, 1)
    except ValueError:
        raise HarnessError(f"README: expected the markers {start!r} and {end!r} around the {what}") from None
    return f"{head}{start}\n{body}\n{end}{tail}"


def readme_with_tables(readme: str, measured: dict) -> str:
    """``readme`` with the text between :data:`README_START` and :data:`README_END` replaced by the
    headline table of ``measured`` (:func:`headline_table`: each map agent against its matched
    twin; the chain positions and every agent's success are on the generated results page).

    Raises:
        HarnessError: the README lacks the markers.
    """
    return replace_between_markers(readme, README_START, README_END, headline_table(measured), "headline tables")


def read_kept_records(path: Path) -> list[dict]:
    """The stripped records a measurement keeps (:data:`RECORDS_FILE`, the sim-to-sim records):
    JSON lines, read strictly (a bad line is a :class:`HarnessError` naming the file and line)."""
    text = Path(path).read_text(encoding="utf-8")
    return [loads_strict(line, source=str(path), line=i, error=HarnessError) for i, line in enumerate(text.splitlines(), 1)
            if line.strip()]


def write_measurement(records_file: Path, records: list[dict], table: str, start: str, end: str, what: str) -> int:
    """Keep a measurement: the README's ``table`` between its markers (``start``, ``end``) and the
    records in ``records_file`` (:func:`write_kept_records`); the exit status of a ``--write``
    (2, with the error on stderr, when the README lacks the markers)."""
    readme = records_file.parents[3] / "README.md"
    try:
        text = replace_between_markers(readme.read_text(), start, end, table, what)
    except HarnessError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    atomic_write_text(readme, text)
    keep = write_kept_records(records_file, records)
    print(f"wrote {records_file} ({len(keep)} records) and the table in {readme}")
    return 0


def write_kept_records(path: Path, records: list[dict]) -> list[dict]:
    """Write the newest record of each episode of ``records`` to ``path`` (atomically), in a stable
    order (suite, encoder, agent, episode, seed), one sorted-key JSON object a line; returns them."""
    keep = sorted(latest_records(records), key=lambda r: (r["suite"], r["encoder"], r["agent"], r["episode_id"], r["seed"]))
    atomic_write_text(path, "".join(json.dumps(r, sort_keys=True) + "\n" for r in keep))
    return keep


def _manifest_sha() -> str:
    return hashlib.sha256((SEALED_FOLDER / MANIFEST_NAME).read_bytes()).hexdigest()


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).resolve().parent).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m harness.report.headline", description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="run folders with results.jsonl over the sealed suites")
    p.add_argument("--write", action="store_true", help=f"write {RECORDS_FILE.name} and {MEASURED_FILE.name} under {DATA_DIR}")
    p.add_argument("--commit", default=None, help="the commit that measured the runs (default: git rev-parse HEAD)")
    args = p.parse_args(argv)
    try:
        records = [strip_record(r) for run in args.runs for r in load_results(Path(run) / "results.jsonl")]
        figures = headline(records)
    except (HarnessError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    measured = {"format": "cf-headline", "version": 1, "commit": args.commit or _commit(), "sealed_manifest_sha256": _manifest_sha(),
                "figures": figures}
    print("\n\n".join((headline_table(measured), positions_table(measured), agents_table(measured))))
    if args.write:
        readme = DATA_DIR.parents[2] / "README.md"
        try:
            text = readme_with_tables(readme.read_text(), measured)
        except HarnessError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        atomic_write_text(readme, text)
        keep = write_kept_records(RECORDS_FILE, records)
        atomic_write_text(MEASURED_FILE, json.dumps(measured, indent=1, sort_keys=True) + "\n")
        print(f"wrote {RECORDS_FILE} ({len(keep)} records), {MEASURED_FILE} and the tables in {readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
