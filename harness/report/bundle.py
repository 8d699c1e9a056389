"""A portable report: one folder (and, if asked, a .zip of it) holding ``report.html``,
``report.md``, the figures, the failure pages and a copy of every replay video they link, with
every link relative and inside the folder, so it works wherever it is moved or mailed.

Maps are large (hundreds of MB a run), so they are left out unless asked (``maps=True``): a map
cell then shows the command that opens it relative to the original run folder, and says so.
``bundle.json`` marks the folder as a bundle (a second bundle into it replaces the first).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

from conceptfusion.errors import HarnessError
from conceptfusion.io_utils import atomic_write_text
from harness.report.links import BUNDLE_MAPS_DIR, ReportLinks
from harness.report.paths import REPLAYS_DIR

__all__ = ["Bundle", "write_bundle", "page_links", "links_outside", "BUNDLE_MARKER"]

_LOG = logging.getLogger(__name__)

BUNDLE_MARKER = "bundle.json"
"""File that marks a folder as a report bundle (what it holds and where it came from)."""

_STORED = (".mp4", ".gif", ".png", ".npz", ".zip")
"""Endings stored in the zip as they are (already compressed)."""


@dataclass(frozen=True)
class Bundle:
    """A written bundle."""

    folder: Path
    zip_path: Path | None
    files: tuple[Path, ...]
    """Every file in the folder, relative to it."""
    videos: int
    maps: int


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.targets: list[str] = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("href", "src") and value:
                self.targets.append(value)


def page_links(html_text: str) -> list[str]:
    """Every ``href`` and ``src`` value of an HTML page, in order."""
    parser = _Links()
    parser.feed(html_text)
    return parser.targets


def links_outside(folder: str | os.PathLike) -> list[str]:
    """``"page: link"`` for every link of every HTML page under ``folder`` that does not resolve
    to a file inside it (in-page anchors and inline ``data:`` images are fine); empty when the
    folder is self-contained."""
    root = Path(folder).resolve()
    bad = []
    for page in sorted(root.rglob("*.html")):
        for target in page_links(page.read_text(encoding="utf-8")):
            if target.startswith(("#", "data:")):
                continue
            parts = urlsplit(target)
            if parts.scheme or parts.netloc or target.startswith("/"):
                bad.append(f"{page.relative_to(root)}: {target} (not a relative link)")
                continue
            resolved = (page.parent / unquote(parts.path)).resolve()
            if not resolved.is_relative_to(root) or not resolved.is_file():
                bad.append(f"{page.relative_to(root)}: {target} (no file inside the bundle)")
    return bad


def _split(dest: Path) -> tuple[Path, Path | None]:
    """(bundle folder, zip file or None) for a ``--bundle`` path: ``x.zip`` -> (``x``, ``x.zip``)."""
    if dest.suffix.lower() == ".zip":
        return dest.with_suffix(""), dest
    return dest, None


def _prepare(folder: Path) -> None:
    """Make ``folder`` ready: new, empty, or a previous bundle (whose files are removed)."""
    if folder.exists() and not folder.is_dir():
        raise HarnessError(f"report bundle: expected a folder (or a .zip path) at {folder}, found a file")
    if not folder.exists() or not any(folder.iterdir()):
        folder.mkdir(parents=True, exist_ok=True)
        return
    if not (folder / BUNDLE_MARKER).is_file():
        raise HarnessError(f"report bundle: {folder} is neither empty nor a previous bundle (no {BUNDLE_MARKER}); "
                           "expected a new or empty folder, so nothing of yours is overwritten")
    for child in folder.iterdir():
        if child.is_dir() and child.name in (REPLAYS_DIR, BUNDLE_MAPS_DIR):
            shutil.rmtree(child)
        elif child.is_file() and (child.suffix in (".html", ".md", ".png") or child.name == BUNDLE_MARKER):
            child.unlink()


def _zip(folder: Path, zip_path: Path) -> None:
    """Write ``folder`` as ``zip_path`` (entries under ``<folder name>/``), through a temporary file."""
    zip_path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{zip_path.name}.", suffix=".tmp", dir=zip_path.parent)
    os.close(fd)
    try:
        with zipfile.ZipFile(tmp, "w") as zf:
            for path in sorted(p for p in folder.rglob("*") if p.is_file()):
                arc = f"{folder.name}/{path.relative_to(folder).as_posix()}"
                method = zipfile.ZIP_STORED if path.name.lower().endswith(_STORED) else zipfile.ZIP_DEFLATED
                zf.write(path, arc, compress_type=method)
        os.replace(tmp, zip_path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_bundle(runs, dest: str | os.PathLike, *, maps: bool = False,
                 title: str = "ConceptFusion harness report") -> Bundle:
    """Write the report of ``runs`` (run folders, as for :func:`harness.report.markdown.write_report`)
    as a bundle at ``dest``: a folder, or, for a path ending ``.zip``, the folder beside it with
    that name less ``.zip`` and the zip of it. ``maps``: copy the final maps in too.

    Raises :class:`~conceptfusion.errors.HarnessError` when ``dest`` is a file or a folder
    holding other things than a previous bundle, or when a page links outside the bundle.
    """
    from harness.report.html import write_html
    from harness.report.markdown import build_report, write_markdown

    folder, zip_path = _split(Path(dest))
    _prepare(folder)
    links = ReportLinks(folder, bundle=True, bundle_maps=maps)
    doc = build_report(runs, folder, title=title, links=links)
    write_markdown(doc)
    write_html(doc)
    run_dirs = sorted({str(Path(b).resolve()) for _, b, _ in doc.items if b is not None})
    n_maps = sum(1 for dst in links.copied.values() if dst.parent.name == BUNDLE_MAPS_DIR)
    atomic_write_text(folder / BUNDLE_MARKER, json.dumps({
        "format": "cf-report-bundle", "version": 1, "runs": run_dirs, "maps": bool(maps),
        "videos": len(links.copied) - n_maps, "map_files": n_maps}, indent=2) + "\n")
    outside = links_outside(folder)
    if outside:
        raise HarnessError(f"report bundle: {len(outside)} link(s) lead outside {folder}: "
                           + "; ".join(outside[:5]) + ("; ..." if len(outside) > 5 else ""))
    if zip_path is not None:
        _zip(folder, zip_path)
    files = tuple(sorted(p.relative_to(folder) for p in folder.rglob("*") if p.is_file()))
    _LOG.info("report bundle %s: %d files", folder, len(files))
    return Bundle(folder, zip_path, files, len(links.copied) - n_maps, n_maps)
