"""A report as data: headings, paragraphs, lists, tables and figures, rendered to Markdown here
and to HTML by :mod:`harness.report.html`.

Every table is built once (:class:`Table` of :class:`Cell`) and drawn by both renderers, so the
Markdown and the HTML report cannot disagree. Inline text may hold Markdown code spans
(`` `suite` ``); the HTML renderer turns them into ``<code>``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Union

__all__ = ["Cell", "Table", "Heading", "Paragraph", "Bullets", "Figure", "Block", "ReportDocument",
           "render_markdown"]


@dataclass(frozen=True)
class Cell:
    """One table cell: its text, plus what only the HTML report uses."""

    text: str
    """What both reports show."""
    sort: float | str | None = None
    """Sort key when the HTML table is sorted by this column (None: the text; NaN sorts last)."""
    href: str | None = None
    """Link target relative to the report folder (Markdown draws ``[text](href)``)."""
    interval: tuple[float, float, float] | None = None
    """(mean, low, high) in [0, 1]: drawn as a small bar with its interval in the HTML report."""
    title: str | None = None
    """Hover text in the HTML report."""
    command: str | None = None
    """A shell command the HTML report shows under the text with a copy button (the map viewer's)."""
    note: str | None = None
    """Small text the HTML report shows under the text: what is missing and why."""


@dataclass(frozen=True)
class Table:
    """A table: a header row and body rows of :class:`Cell` (or plain strings)."""

    head: tuple[str, ...]
    rows: list[tuple[Union[Cell, str], ...]] = field(default_factory=list)
    markdown: bool = True
    """False: only the HTML report draws it (e.g. one row per episode)."""
    name: str = ""
    """A stable identifier (the HTML ``id``), for tests and links."""
    caption: str = ""
    """Shown above the table in the HTML report (the Markdown report has headings for that)."""
    row_kinds: tuple[str, ...] = ()
    """Empty, or one word per row that the HTML report marks the row with (``failed``, ``miss``)."""

    def __post_init__(self) -> None:
        for i, row in enumerate(self.rows):
            if len(row) != len(self.head):
                raise ValueError(f"Table {self.name or self.head[0]!r}: row {i} has {len(row)} cells, "
                                 f"expected {len(self.head)} (the header's)")
        if self.row_kinds and len(self.row_kinds) != len(self.rows):
            raise ValueError(f"Table {self.name or self.head[0]!r}: {len(self.row_kinds)} row kinds for "
                             f"{len(self.rows)} rows")


@dataclass(frozen=True)
class Heading:
    """A section title; ``level`` 1-4."""

    level: int
    text: str


@dataclass(frozen=True)
class Paragraph:
    """A line of text."""

    text: str


@dataclass(frozen=True)
class Bullets:
    """A bulleted list."""

    items: tuple[str, ...]


@dataclass(frozen=True)
class Figure:
    """A PNG figure written beside the report (``file``) with its alt text."""

    file: str
    alt: str


Block = Union[Heading, Paragraph, Bullets, Table, Figure]


@dataclass
class ReportDocument:
    """A built report: its blocks, the figures they name (file name -> PNG bytes), and the
    records it was built from with the folder each came from (``None`` for records passed
    directly without ``base_dir``)."""

    title: str
    out_dir: Path
    blocks: list[Block]
    figures: dict[str, bytes]
    items: list[tuple[dict, Path | None]]


def _md_cell(cell: Cell | str) -> str:
    c = cell if isinstance(cell, Cell) else Cell(str(cell))
    text = c.text.replace("|", "\\|")
    return f"[{text}]({c.href})" if c.href else text


def _md_alt(text: str) -> str:
    return text.replace("[", "(").replace("]", ")")


def _md_block(block: Block) -> list[str]:
    if isinstance(block, Heading):
        return ["#" * block.level + " " + block.text]
    if isinstance(block, Paragraph):
        return [block.text]
    if isinstance(block, Bullets):
        return [f"- {item}" for item in block.items]
    if isinstance(block, Figure):
        return [f"![{_md_alt(block.alt)}]({block.file})"]
    if isinstance(block, Table):
        return (["| " + " | ".join(_md_cell(h) for h in block.head) + " |", "|" + "---|" * len(block.head)]
                + ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows])
    raise TypeError(f"report block: expected Heading, Paragraph, Bullets, Table or Figure, got {type(block).__name__}")


def render_markdown(doc: ReportDocument) -> str:
    """The Markdown text of a report: the title, then every block followed by a blank line
    (tables marked ``markdown=False`` left out)."""
    lines = [f"# {doc.title}", ""]
    for block in doc.blocks:
        if isinstance(block, Table) and not block.markdown:
            continue
        lines += _md_block(block) + [""]
    return "\n".join(lines)
