"""A report as data: headings, paragraphs, lists, tables and figures, rendered to Markdown here
and to HTML by :mod:`harness.report.html`.

Every table is built once (:class:`Table` of :class:`Cell`) and drawn by both renderers, so the
Markdown and the HTML report cannot disagree. A table's columns may sit in named groups (a
two-row header in the HTML report, where a group can be hidden; ``group: column`` in Markdown).
The report opens on :class:`Cards`, one :class:`Card` per suite answering its question (a grid
in the HTML report, a compact table in Markdown). Inline text may hold Markdown code spans
(`` `suite` ``); the HTML renderer turns them into ``<code>``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Union

__all__ = ["Cell", "Table", "Heading", "Paragraph", "Bullets", "Figure", "Card", "Cards", "Block", "ReportDocument",
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
    groups: tuple[str, ...] = ()
    """Empty, or one group name per column (``""``: in no group); a group's columns are adjacent."""
    collapsed: tuple[str, ...] = ()
    """Groups the HTML report starts hidden (a toggle shows them); Markdown shows every column."""

    def __post_init__(self) -> None:
        what = f"Table {self.name or self.head[0]!r}"
        for i, row in enumerate(self.rows):
            if len(row) != len(self.head):
                raise ValueError(f"{what}: row {i} has {len(row)} cells, expected {len(self.head)} (the header's)")
        if self.row_kinds and len(self.row_kinds) != len(self.rows):
            raise ValueError(f"{what}: {len(self.row_kinds)} row kinds for {len(self.rows)} rows")
        if self.groups and len(self.groups) != len(self.head):
            raise ValueError(f"{what}: {len(self.groups)} group names for {len(self.head)} columns (expected one per column)")
        runs = [g for i, g in enumerate(self.groups) if g and (i == 0 or self.groups[i - 1] != g)]
        if len(runs) != len(set(runs)):
            raise ValueError(f"{what}: the columns of a group must be adjacent; groups in column order: {list(self.groups)}")
        unknown = sorted(set(self.collapsed) - set(runs))
        if unknown:
            raise ValueError(f"{what}: collapsed groups {unknown} are not groups of the table (groups: {runs})")

    def column_names(self) -> tuple[str, ...]:
        """Each column's full name: ``group: column``, or the column's alone when in no group."""
        groups = self.groups or ("",) * len(self.head)
        return tuple(f"{g}: {h}" if g else h for g, h in zip(groups, self.head))


@dataclass(frozen=True)
class Heading:
    """A section title; ``level`` 1-4."""

    level: int
    text: str
    anchor: str = ""
    """The HTML ``id`` to link the section by (empty: made from the text)."""


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


@dataclass(frozen=True)
class Card:
    """One suite's answer on the report's first screen; every field is display text."""

    title: str
    """The suite's name."""
    question: str
    """What the suite answers, in plain words."""
    best: str
    """The best agent (``agent (encoder)``), ``(privileged)`` when it read ground truth."""
    figure: str
    """Its headline metric: ``success 0.83 [0.72, 0.90] (n 64)``."""
    against: str = ""
    """What it is compared with and that one's figure (empty: no comparison)."""
    difference: str = ""
    """The paired difference with its 95% interval: ``+0.03 [-0.03, +0.11]``."""
    test: str = ""
    """p and the number of pairs: ``p 0.69 (exact McNemar), 64 pairs``."""
    verdict: str = ""
    """``map helps``, ``no detectable difference``, ``map hurts`` (or the suite's words)."""
    tone: str = ""
    """``better``, ``same``, ``worse`` or empty: how the HTML report colours the verdict."""
    note: str = ""
    """A line under the figures (a privileged result that scores higher, too few pairs)."""
    href: str = ""
    """Where the suite's section is (``#anchor``)."""
    interval: tuple[float, float, float] | None = None
    """(mean, low, high) in [0, 1] of the best figure: drawn as a bar in the HTML report."""


@dataclass(frozen=True)
class Cards:
    """The first screen: one :class:`Card` per suite."""

    cards: tuple[Card, ...]
    name: str = "headline"
    """The HTML ``id`` of the grid."""


Block = Union[Heading, Paragraph, Bullets, Table, Figure, Cards]


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
        return (["| " + " | ".join(_md_cell(h) for h in block.column_names()) + " |", "|" + "---|" * len(block.head)]
                + ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows])
    if isinstance(block, Cards):
        return _md_cards(block)
    raise TypeError(f"report block: expected Heading, Paragraph, Bullets, Table, Figure or Cards, got {type(block).__name__}")


def _md_cards(block: Cards) -> list[str]:
    """The cards as one compact table (a row per suite), their notes as a list under it."""
    head = ("suite", "question", "best", "figure", "against", "difference [95% CI]", "test", "verdict")
    rows = [(f"`{c.title}`", c.question, c.best, c.figure, c.against or "-",
             c.difference or "-", c.test or "-", c.verdict or "-") for c in block.cards]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in rows]
    notes = [f"- `{c.title}`: {c.note}" for c in block.cards if c.note]
    return lines + ([""] + notes if notes else [])


def render_markdown(doc: ReportDocument) -> str:
    """The Markdown text of a report: the title, then every block followed by a blank line
    (tables marked ``markdown=False`` left out)."""
    lines = [f"# {doc.title}", ""]
    for block in doc.blocks:
        if isinstance(block, Table) and not block.markdown:
            continue
        lines += _md_block(block) + [""]
    return "\n".join(lines)
