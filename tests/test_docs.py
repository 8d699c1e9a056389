"""The documentation: a short README whose links resolve, and the docs site (MkDocs, strict mode:
a broken link, a missing image or a page outside the navigation fails the build)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
README_MAX_LINES = 250


def test_the_readme_is_short_and_its_local_links_resolve():
    text = (REPO / "README.md").read_text()
    assert len(text.splitlines()) <= README_MAX_LINES
    links = re.findall(r"\]\(([^)#\s]+)\)", text)
    local = [link for link in links if not re.match(r"[a-z]+://", link)]
    assert local and all((REPO / link).exists() for link in local), [link for link in local if not (REPO / link).exists()]
    # every page of the site is one the README points to (the model card and history included)
    pages = {p.name for p in (REPO / "docs").glob("*.md") if p.name != "index.md"}
    assert pages == {Path(link).name for link in local if link.startswith("docs/") and link.endswith(".md")}


def test_every_page_is_in_the_site_navigation():
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text())["nav"]
    listed = {page for entry in nav for page in entry.values()}
    assert listed == {p.name for p in (REPO / "docs").glob("*.md")}


def test_the_docs_site_builds_in_strict_mode(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(REPO / "mkdocs.yml"),
                           "-d", str(tmp_path / "site")], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "WARNING" not in done.stderr
    built = {p.parent.name for p in (tmp_path / "site").glob("*/index.html")}
    assert {"environments", "regression-gate", "results"} <= built
    api = (tmp_path / "site" / "api" / "index.html").read_text()  # rendered from the docstrings (mkdocstrings)
    for name in ("register_encoder", "make_mapper", "register_agent", "RGBDFrame", "load_map"):
        assert re.search(rf'id="[a-z_.]+\.{name}"', api), name
    assert "Example" in api and "Raises" in api


def test_the_first_hour_benchmark_reads_the_readme_quickstart():
    """``benchmarks/bench_first_hour.py`` times the README's quickstart run literally: it finds
    the demo, a small run that writes a report, and the viewer."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        from bench_first_hour import quickstart_commands
    finally:
        sys.path.remove(str(REPO / "benchmarks"))
    cmds = quickstart_commands((REPO / "README.md").read_text())
    assert [c.split()[:2] for c in cmds] == [["cfharness", "demo"], ["cfharness", "run"], ["cfharness", "view"]]
    assert "--out runs/" in cmds[1] and "#" not in " ".join(cmds)
