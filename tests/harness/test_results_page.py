"""The documentation's results page is generated (``cfharness report RUN --results-page``): the
sealed headline recomputed from the shipped records, then a run's report tables, with no figures
and no links into a run folder; the page checked into ``docs/`` agrees with the records."""

import re
from pathlib import Path

import numpy as np

from harness.cli import main
from harness.report.headline import RECORDS_FILE, headline, headline_table, positions_table
from harness.report.results_page import results_page
from harness.runner.results import append_record
from conceptfusion.strict_json import loads_strict
from tests.harness.test_report import _records

DOCS_PAGE = Path(__file__).resolve().parents[2] / "docs" / "results.md"


def _sealed_tables() -> tuple[str, str]:
    lines = [ln for ln in RECORDS_FILE.read_text().splitlines() if ln.strip()]
    measured = {"figures": headline([loads_strict(ln, source="records", line=i, error=ValueError) for i, ln in enumerate(lines, 1)])}
    return headline_table(measured), positions_table(measured)


def _run(tmp_path) -> Path:
    run = tmp_path / "run"
    run.mkdir()
    for r in _records(np.random.default_rng(0)):
        append_record(run / "results.jsonl", r)
    return run


def test_the_page_recomputes_the_sealed_headline_and_carries_the_runs_tables(tmp_path):
    page = results_page([_run(tmp_path)])
    twins, positions = _sealed_tables()
    assert twins in page and positions in page
    assert page.startswith("# Measured results") and "This page is generated" in page
    assert "## The default comparison" in page and "### Suite `search`" in page and "map-navigator" in page
    assert "![" not in page and ".png" not in page  # no figures
    links = re.findall(r"\]\(([^)]+)\)", page)
    assert links == ["measurement-history.md"]  # nothing points into a run folder


def test_the_command_writes_the_page_and_refuses_an_empty_run(tmp_path, capsys):
    out = tmp_path / "results.md"
    assert main(["report", str(_run(tmp_path)), "--results-page", str(out)]) == 0
    assert out.read_text() == results_page([tmp_path / "run"])
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "results.jsonl").write_text("")
    assert main(["report", str(empty), "--results-page", str(tmp_path / "x.md")]) == 2
    assert "cfharness report:" in capsys.readouterr().err and not (tmp_path / "x.md").exists()


def test_the_checked_in_page_was_generated_and_agrees_with_the_sealed_records():
    text = DOCS_PAGE.read_text()
    assert "This page is generated" in text
    twins, positions = _sealed_tables()
    assert twins in text and positions in text
