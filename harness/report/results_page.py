"""The documentation's results page (``docs/results.md``), generated, never typed.

``cfharness report RUN... --results-page docs/results.md`` writes one Markdown page from:

- the sealed test set's headline: the records the headline was measured from
  (:data:`~harness.report.headline.RECORDS_FILE`, shipped with the package), recomputed here
  (:func:`~harness.report.headline.headline`) into the twins table, the chain positions and
  every agent's success;
- the given run folders (the default comparison, ``cfharness run``): the report's first screen
  (one card per suite) and its per-suite tables, as ``report.md`` has them, without figures and
  per-episode rows (those stay in the run's ``report.html``).

The page names the commit and the runs it was written from. How the figures moved over time is
``docs/measurement-history.md``, written by hand.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path

from conceptfusion.io_utils import atomic_write_text
from harness.report.document import Cell, Figure, Heading, Table, render_markdown
from harness.report.headline import MEASURED_FILE, RECORDS_FILE, agents_table, read_kept_records, headline, headline_table, positions_table
from harness.report.markdown import build_report
from harness.runner.results import load_results

__all__ = ["results_page", "write_results_page"]

_INTRO = """# Measured results

This page is generated: `cfharness report RUN... --results-page docs/results.md` wrote it from the
records named below; do not edit it by hand. Intervals are 95% (Wilson for rates, bootstrap for
paired differences); p is the exact McNemar test on paired episodes. `oracle-open` and the
oracles are privileged (they read ground truth a robot does not have): upper bounds, not robots.
How the figures moved over time is on [Measurement history](measurement-history.md).
"""


def _sealed_section(records_file: Path) -> list[str]:
    records = read_kept_records(records_file)
    measured = {"figures": headline(records)}
    commit = ""
    if MEASURED_FILE.is_file() and records_file == RECORDS_FILE:
        commit = str(json.loads(MEASURED_FILE.read_text()).get("commit", "")).split()[0]
    return [
        "## The sealed test set",
        "",
        "Each map agent against its matched map-free twin on the sealed episodes (`scenes/sealed-v2/`), measured once"
        + (f" at commit `{commit[:7]}`" if commit else "") + f"; {len(records)} records in "
        "`harness/data/sealed/records.jsonl`, recomputed for this page (`cfharness develop headline` wrote them).",
        "",
        headline_table(measured), "", "Success per position in a chain (the first k goals reached in a row):", "",
        positions_table(measured), "", "Every agent's success:", "", agents_table(measured), "",
    ]


_FIGURE_SECTIONS = ("Query heatmaps",)
"""Report sections that hold figures only (with their captions): left out of the page."""


def _sim_section() -> list[str]:
    """The MuJoCo-against-PyBullet table from the kept records (:mod:`harness.report.sim_to_sim`), when there are any."""
    from harness.report.sim_to_sim import RECORDS_FILE as SIM_RECORDS, sim_to_sim, sim_to_sim_table

    if not SIM_RECORDS.is_file():
        return []
    return ["## MuJoCo against PyBullet", "",
            "The same sealed searches, agents and perception in both simulators, paired by episode "
            "(`cfharness develop sim-to-sim` kept the records in `harness/data/sim_to_sim/records.jsonl`):", "",
            sim_to_sim_table(sim_to_sim(read_kept_records(SIM_RECORDS))), ""]


def _instruct_section() -> list[str]:
    """The planner-in-the-loop table from the kept records (:mod:`harness.report.instruct`), when there are any."""
    from harness.report.instruct import RECORDS_FILE as INSTRUCT_RECORDS, instruct_rows, instruct_table

    if not INSTRUCT_RECORDS.is_file():
        return []
    return ["## A language planner with and without the map", "",
            "`instruct-v2`: the same planner and navigator told what the map holds (`map-planner`) or the instruction "
            "alone (`generic-planner`), paired by episode (`cfharness develop instruct` kept the records in "
            "`harness/data/instruct/records.jsonl`):", "",
            instruct_table(instruct_rows(read_kept_records(INSTRUCT_RECORDS))), ""]


def _page_blocks(blocks: list) -> list:
    """A report's blocks for this page: no figures or figure-only sections, no links (they point
    into a run's report folder), no headings left with nothing under them, and not the report's
    list of skipped figures."""
    out, skip_level = [], None
    for b in blocks:
        if isinstance(b, Heading):
            if skip_level is not None and b.level > skip_level:
                continue
            skip_level = b.level if b.text in _FIGURE_SECTIONS or b.text == "Skipped" else None
            if skip_level is not None:
                continue
        elif skip_level is not None or isinstance(b, Figure):
            continue
        if isinstance(b, Table):
            b = dataclasses.replace(b, rows=[tuple(dataclasses.replace(c, href=None) if isinstance(c, Cell) else c for c in row)
                                             for row in b.rows])
        out.append(b)
    kept = []
    for i, b in enumerate(out):  # a heading followed by a heading of its level or above, or by nothing: empty
        nxt = out[i + 1] if i + 1 < len(out) else None
        if isinstance(b, Heading) and (nxt is None or (isinstance(nxt, Heading) and nxt.level <= b.level)):
            continue
        kept.append(b)
    return kept


def _runs_section(runs: list, title: str) -> list[str]:
    with tempfile.TemporaryDirectory(prefix="cf-results-page-") as tmp:  # the figures are drawn and dropped
        doc = build_report(runs, tmp)
    body = render_markdown(dataclasses.replace(doc, title=title, blocks=_page_blocks(doc.blocks)))
    # one level down: the report's sections become sections of this page's
    return ["\n".join("#" + line if line.startswith("#") else line for line in body.splitlines()), ""]


def results_page(runs: list, *, records_file: str | os.PathLike = RECORDS_FILE,
                 title: str = "The default comparison") -> str:
    """The page's Markdown: the sealed headline recomputed from ``records_file``, then the report
    tables of ``runs`` (run folders or results files) under ``title``.

    Raises:
        ValueError: the runs hold no records (from :func:`~harness.report.markdown.build_report`).
    """
    run_ids = sorted({str(r.get("run_id")) for run in runs for r in load_results(Path(run) / "results.jsonl"
                                                                               if Path(run).is_dir() else run)})
    parts = [_INTRO, *_sealed_section(Path(records_file)), *_sim_section(), *_instruct_section()]
    parts += [f"Run{'s' if len(run_ids) > 1 else ''} {', '.join(f'`{r}`' for r in run_ids)} "
              "(`cfharness run`, the default comparison: slices of the agent suites and the map suites):", ""]
    parts += _runs_section(list(runs), title)
    return "\n".join(parts).rstrip() + "\n"


def write_results_page(runs: list, path: str | os.PathLike, **kwargs) -> Path:
    """Write :func:`results_page` to ``path`` atomically; returns the path."""
    return atomic_write_text(path, results_page(runs, **kwargs))
