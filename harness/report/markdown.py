"""A Markdown report of one or more evaluation runs, with its PNG figures.

:func:`write_report` reads run folders (their ``results.jsonl``) or takes records directly and
writes ``report.md`` plus the figures it links into one folder, every file atomically. The report
is built once as data (:func:`build_report`, blocks of :mod:`harness.report.document`) and
rendered to Markdown here and to a self-contained HTML page by :mod:`harness.report.html`:

- first, the headline: one card per suite with the question it answers, the best agent, its
  difference to its matched twin or the suite's baseline with the 95% interval, p and n, and a
  verdict (:mod:`harness.report.cards`); the suites' sections follow in the cards' order;
- a run summary (episodes, statuses, suites, agents, encoders, total wall time, and which
  agents read ground truth a robot does not have: records with ``extras.privileged``);
- per suite, a table of every (agent, encoder) with each metric the suite's records have and
  its 95% interval, under readable names in groups (:mod:`harness.report.labels`; the HTML report
  starts wide tables with the headline's group only), the failed/timed-out count when some
  episode did not finish and the wall time per episode (privileged groups marked "(privileged)"
  beside their encoder), and a bar chart of success;
- per suite, paired comparisons: first each map-equipped agent against its matched map-free twin
  (``extras.twin_of``), then against every other map-free one (``extras.uses_map``; when some
  group lacks it, every pair of groups is compared);
- per suite, success per goal category, and per way the goal was named (v2 episodes);
- per suite run with several seeds (``--seeds``), each agent's success over seeds with its
  between-seed spread (std and min-max of the per-seed rates), and every pair of agents whose
  difference is within that noise flagged;
- with several runs, per suite the success of every run side by side;
- for agents whose records carry ``extras.path_xy``, a top-down view of a few failed and
  successful episodes over the floor plan of ``extras.scene`` (a path under ``scenes/``) with
  goal text, start, end and success region (:mod:`harness.report.figures`);
- per suite with failures, their count per cause and agent, linking the suite's failure page
  ``failures-<suite>.html`` (:mod:`harness.report.failures`);
- per suite, one row per episode (HTML only: :mod:`harness.report.episodes`), failures first,
  with goal, category and cause, linking the episode's replay video and map when
  ``RUN/replays`` holds them;
- for records with ``extras.heatmap_npz`` (written by :mod:`harness.maps.query`), a top-down
  heatmap of the query over the table with its ground truth and verdict. A relative path is
  taken from the run folder the record came from (from ``base_dir`` for records passed directly).

What cannot be drawn (no categories, a missing scene or heatmap file) is skipped, and the
report's last section says what was skipped and why.
"""

from __future__ import annotations

import math
import os
import re
from collections import Counter
from pathlib import Path


from conceptfusion.errors import HarnessError, MissingFileError
from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text
from harness.report import figures as report_figures
from harness.report import plots as report_plots
from harness.report.cards import answer_card, section_anchor, suite_answers
from harness.report.episodes import episode_table
from harness.report.failures import failure_section
from harness.report.links import ReportLinks
from harness.report.document import Bullets, Cards, Cell, Figure, Heading, Paragraph, ReportDocument, Table, render_markdown
from harness.report.labels import column_order, metric_label
from harness.runner.results import RESULTS_FILE, ResultsFormatError, load_results, record_key, warn_record_problems
from harness.report.stats import group_key, paired_comparison, per_category, seed_spread, summarize, wilson_interval, within_noise

__all__ = ["write_report", "build_report", "write_markdown", "REPORT_FILE"]

REPORT_FILE = "report.md"
_MAX_PAIRS = 24
_TABLE_BOX_PX = 1232
"""Width of the HTML report's content box: a suite table starts with the column groups that fit
in it shown (the headline metric's group always, then the others in column order) and the rest
hidden, one click away."""


def _collect(inputs, base_dir) -> list[tuple[dict, Path | None, str]]:
    """(record, folder its relative paths start from, run label) for every input; the label is
    the run folder as given, or the record's ``run_id`` for records passed directly."""
    items = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    if not items:
        raise ValueError("write_report: expected run folders or records, got an empty sequence")
    out: list[tuple[dict, Path | None, str]] = []
    for item in items:
        if isinstance(item, dict):
            out.append((item, Path(base_dir) if base_dir is not None else None, str(item.get("run_id"))))
        elif isinstance(item, (str, os.PathLike)):
            p = Path(item)
            results = p / RESULTS_FILE if p.is_dir() else p
            if not results.is_file():
                raise MissingFileError(f"write_report: no results at {results} (expected a run folder holding "
                                       f"{RESULTS_FILE}, or a results file)")
            out.extend((r, results.parent, str(results.parent)) for r in load_results(results))
            if p.is_dir():
                warn_record_problems(p)  # another run's records, two outcomes of one episode
        else:
            raise TypeError(f"write_report: expected run folders (paths) or records (dicts), got {type(item).__name__}")
    return out


def _fmt(stat) -> str:
    """``mean [low, high]``: two decimals below 10, one below 100, none above (the interval as its mean)."""
    if stat is None:
        return "-"
    top = max(abs(stat.mean), 0.0 if math.isnan(stat.high) else abs(stat.high))
    d = 2 if top < 10 else 1 if top < 100 else 0
    if math.isnan(stat.low):
        return f"{stat.mean:.{d}f}"
    return f"{stat.mean:.{d}f} [{stat.low:.{d}f}, {stat.high:.{d}f}]"


def _stat_cell(stat) -> Cell:
    """A metric cell: its text, sorted by the mean, with the interval drawn for rates."""
    if stat is None:
        return Cell("-", sort=math.nan)
    bar = (stat.mean, stat.low, stat.high) if stat.rate and not math.isnan(stat.low) else None
    return Cell(_fmt(stat), sort=stat.mean, interval=bar)


def _fmt_seconds(s: float) -> str:
    if not math.isfinite(s):
        return "-"
    if s < 120:
        return f"{s:.1f} s"
    h, rem = divmod(int(round(s)), 3600)
    return f"{h}:{rem // 60:02d}:{rem % 60:02d}"


class _Writer:
    """Collects figure files (unique names) and skipped-item notes while the report is built."""

    def __init__(self, out_dir: Path):
        self.out_dir = out_dir
        self.figures: dict[str, bytes] = {}
        self.skipped: list[str] = []

    def figure(self, stem: str, png: bytes) -> str:
        base = re.sub(r"[^A-Za-z0-9._-]+", "-", stem).strip("-") or "figure"
        name, i = f"{base}.png", 1
        while name in self.figures:
            i += 1
            name = f"{base}-{i}.png"
        self.figures[name] = png
        atomic_write_bytes(self.out_dir / name, png)
        return name

    def skip(self, what: str, why: str) -> None:
        self.skipped.append(f"{what}: {why}")


def _privileged(records) -> set[tuple[str, str]]:
    """The (agent, encoder) groups with a record that read ground truth (``extras.privileged``)."""
    return {group_key(r)[1:] for r in records if (r.get("extras") or {}).get("privileged") is True}


def _summary_section(records) -> list:
    statuses = Counter(r["status"] for r in records)
    walls = [float(r["timings"]["wall_s"]) for r in records if "wall_s" in (r.get("timings") or {})]
    groups = {group_key(r) for r in records}
    privileged = sorted(_privileged(records))
    return [Heading(2, "Run summary"), Bullets((
        f"episodes: {len(records)} ({', '.join(f'{k} {v}' for k, v in sorted(statuses.items()))})",
        f"runs: {', '.join(sorted({str(r.get('run_id')) for r in records}))}",
        f"suites: {', '.join(sorted({r['suite'] for r in records}))}",
        f"agents: {', '.join(sorted({g[1] for g in groups}))}",
        f"encoders: {', '.join(sorted({g[2] for g in groups}))}",
        f"total episode wall time: {_fmt_seconds(sum(walls)) if walls else 'not recorded'}",
        "privileged (read ground truth a robot does not have): "
        + (", ".join(f"{a} ({e})" for a, e in privileged) if privileged else "none"),
    ))]


def _suite_table(rows, suite: str, privileged: set[tuple[str, str]] = frozenset(), headline: str | None = None) -> Table:
    """Every (agent, encoder) of a suite, the best by the headline metric first: each metric some
    row has (mean [95% CI]) under its readable name and group, the headline metric's group first;
    the failed/timeout column only when some episode did not finish, the wall time only when
    recorded."""
    first = metric_label(headline)[0] if headline else None
    metrics = column_order({m for r in rows for m in r.metrics}, first_group=first)
    labels = [metric_label(m) for m in metrics]
    unfinished = any(r.n_failed or r.n_timeout for r in rows)
    timed = any(math.isfinite(r.wall_s) for r in rows)
    head = ("agent", "encoder", "n", *(("failed/timeout",) if unfinished else ()), *(c for _, c in labels),
            *(("s/episode",) if timed else ()))
    groups = ("", "", "", *(("",) if unfinished else ()), *(g for g, _ in labels), *(("",) if timed else ()))
    body = []
    ranked = sorted(rows, key=lambda r: -r.metrics[headline].mean if headline in r.metrics else math.inf)  # stable: by name next
    for r in ranked:
        encoder = f"{r.encoder} (privileged)" if (r.agent, r.encoder) in privileged else r.encoder
        body.append((r.agent, encoder, Cell(str(r.n), sort=r.n),
                     *((Cell(f"{r.n_failed}/{r.n_timeout}", sort=r.n_failed + r.n_timeout),) if unfinished else ()),
                     *(_stat_cell(r.metrics.get(m)) for m in metrics),
                     *((Cell(_fmt_seconds(r.wall_s), sort=r.wall_s),) if timed else ())))
    named = [g for g in dict.fromkeys(groups) if g]
    collapsed = _groups_past_the_box(head, groups, body, first)
    return Table(head, body, name=f"suite-{suite}", groups=groups if named else (), collapsed=collapsed,
                 caption="Each metric: mean [95% interval] over the episodes (Wilson for rates, bootstrap for means)"
                         + ("; column groups not shown start hidden (the buttons show them)" if collapsed else ""))


def _column_px(label: str, cells) -> int:
    """A rough width of an HTML table column: 7 px a character at the page's 13 px font, 17 px of
    padding and border, 54 px more when its cells draw an interval bar."""
    texts = [label] + [c.text if isinstance(c, Cell) else str(c) for c in cells]
    bar = any(isinstance(c, Cell) and c.interval is not None for c in cells)
    return 17 + 7 * max(len(t) for t in texts) + (54 if bar else 0)


def _groups_past_the_box(head, groups, body, first: str | None) -> tuple[str, ...]:
    """The column groups the HTML report starts hidden: those that no longer fit
    :data:`_TABLE_BOX_PX` once the ungrouped columns, the headline's group and the groups before
    them in column order are shown."""
    widths = [_column_px(h, [row[i] for row in body]) for i, h in enumerate(head)]
    used = sum(w for w, g in zip(widths, groups) if not g)
    order = list(dict.fromkeys(g for g in groups if g))
    if first in order:
        order.remove(first)
        order.insert(0, first)
    hidden = []
    for g in order:
        width = sum(w for w, gg in zip(widths, groups) if gg == g)
        if g != first and (hidden or used + width > _TABLE_BOX_PX):
            hidden.append(g)
        else:
            used += width
    return tuple(hidden)


def _runs_side_by_side(run_items, suite: str) -> list:
    """Success of every (agent, encoder) in each run of ``suite``, one column per run."""
    runs = sorted({label for _, _, label in run_items})
    per_run = {label: {(row.agent, row.encoder): row for row in summarize(
        [r for r, _, lab in run_items if lab == label and r["suite"] == suite], ("success",))} for label in runs}
    groups = sorted({g for rows in per_run.values() for g in rows})
    if not groups or not any("success" in row.metrics for rows in per_run.values() for row in rows.values()):
        return []
    head = ("agent", "encoder", *(f"{label}: success [95% CI] (n)" for label in runs))
    body = []
    for g in groups:
        cells = []
        for label in runs:
            row = per_run[label].get(g)
            stat = row.metrics.get("success") if row else None
            c = _stat_cell(stat)
            cells.append(Cell(f"{c.text} ({row.n})", sort=c.sort, interval=c.interval) if row else c)
        body.append((g[0], g[1], *cells))
    return [Heading(3, "Runs side by side"), Table(head, body, name=f"runs-{suite}")]


def _uses_map(records) -> dict[tuple[str, str], bool | None]:
    out: dict[tuple[str, str], bool | None] = {}
    for r in records:
        _, agent, enc = group_key(r)
        flag = (r.get("extras") or {}).get("uses_map")
        prev = out.get((agent, enc), "unset")
        if prev == "unset":
            out[(agent, enc)] = flag if isinstance(flag, bool) else None
        elif prev != flag:
            out[(agent, enc)] = None
    return out


def _twins(records) -> dict[tuple[str, str], tuple[str, str]]:
    """(twin agent, encoder) -> (the map agent it is the matched twin of, same encoder), for the
    groups whose records name one (``extras.twin_of``)."""
    out = {}
    for r in records:
        _, agent, enc = group_key(r)
        of = (r.get("extras") or {}).get("twin_of")
        if isinstance(of, str) and of:
            out[(agent, enc)] = (of, enc)
    return out


def _twin_section(records, suite: str, w: _Writer) -> list:
    """Each map agent against its matched map-free twin (the suite's first table): the value of
    fused semantics, everything else equal. Empty when no twin ran beside its map agent."""
    flags = _uses_map(records)
    matched = sorted((m, t) for t, m in _twins(records).items() if m in flags)
    if not matched:
        return []
    return [Heading(3, "Map agent against its matched map-free twin"),
            Paragraph("The twin sees the same views, explores, plans and decides by the same rules and keeps the same "
                      "geometry; its concept vectors are not fused across views (each frame is perceived alone). The "
                      "difference is the value of the ConceptFusion map itself.")] + _pairs_table(records, suite, matched, w,
                                                                                                 name=f"twins-{suite}")


def _comparisons(records, suite: str, w: _Writer) -> list:
    """Paired comparisons of map-equipped agents against the map-free ones other than their twin
    (:func:`_twin_section`): the weak and random references."""
    flags = _uses_map(records)
    groups = sorted(flags)
    twins = {t: m for t, m in _twins(records).items() if m in flags}
    blocks: list = []
    if all(isinstance(f, bool) for f in flags.values()):
        pairs = [(a, b) for a in groups if flags[a] for b in groups if not flags[b] and twins.get(b) != a]
        basis = ("map-equipped agents against the weak and random references" if twins
                 else "map-equipped vs map-free agents (extras.uses_map)")
    else:
        pairs = [(a, b) for i, a in enumerate(groups) for b in groups[i + 1:]]
        basis = "every pair of agents (extras.uses_map not recorded for all)"
    if not pairs:
        w.skip(f"paired comparisons, suite {suite}", "no pair of agents to compare " + f"({basis})")
        return blocks
    if len(pairs) > _MAX_PAIRS:
        w.skip(f"paired comparisons, suite {suite}", f"{len(pairs) - _MAX_PAIRS} of {len(pairs)} pairs left out")
        pairs = pairs[:_MAX_PAIRS]
    return blocks + [Heading(3, f"Paired comparisons: {basis}")] + _pairs_table(records, suite, pairs, w, name=f"pairs-{suite}")


def _pairs_table(records, suite: str, pairs, w: _Writer, *, name: str) -> list:
    """A table of paired comparisons of (agent, encoder) groups, with how they were tested; empty
    when the records hold no comparable metric."""
    metrics = [m for m in ("success", "spl", "accuracy", "macc", "fmiou", "text_miou")
               if any(m in (r.get("metrics") or {}) for r in records)]
    if not metrics:
        w.skip(f"paired comparisons, suite {suite}", "no success, SPL, accuracy or mIoU metric to compare")
        return []
    head = ("A", "B", "metric", "pairs", "A mean", "B mean", "A - B [95% CI]", "A only / B only", "p")
    body = []
    for (a, ea), (b, eb) in pairs:
        for metric in metrics:
            try:
                res = paired_comparison(records, a, b, metric, suite=suite, encoder=ea, encoder_b=eb)
            except ValueError as exc:
                w.skip(f"comparison {a} ({ea}) vs {b} ({eb}), {metric}, suite {suite}", str(exc))
                continue
            disc = f"{res.a_only} / {res.b_only}" if res.binary else "-"
            body.append((f"{a} ({ea})", f"{b} ({eb})", metric, Cell(str(res.n_pairs), sort=res.n_pairs),
                         Cell(f"{res.mean_a:.2f}", sort=res.mean_a), Cell(f"{res.mean_b:.2f}", sort=res.mean_b),
                         Cell(f"{res.mean_diff:+.2f} [{res.ci_low:+.2f}, {res.ci_high:+.2f}]", sort=res.mean_diff),
                         Cell(disc, sort=(res.a_only - res.b_only) if res.binary else math.nan),
                         Cell(f"{res.p_value:.3g}", sort=res.p_value)))
    return [Paragraph("Episodes paired by suite, episode id and seed; p: exact McNemar for rates, Wilcoxon "
                      "signed-rank otherwise."), Table(head, body, name=name)]


def _seed_spread_section(records, suite: str) -> list:
    """Per (agent, encoder) of ``suite``: success over seeds with its between-seed spread, and
    each pair's difference against their combined spread (:func:`~harness.report.stats.within_noise`).
    Empty when no group ran more than one seed."""
    spreads = [s for s in seed_spread(records) if len(s.seeds) > 1]
    if not spreads:
        return []
    head = ("agent", "encoder", "seeds", "episodes", "success (mean over seeds)", "between-seed std", "min - max")
    body = [(s.agent, s.encoder, Cell(str(len(s.seeds)), sort=len(s.seeds)), Cell(str(s.episodes), sort=s.episodes),
             Cell(f"{s.mean:.3f}", sort=s.mean), Cell(f"{s.std:.3f}", sort=s.std),
             Cell(f"{s.low:.3f} - {s.high:.3f}", sort=s.high - s.low)) for s in spreads]
    pair_head = ("A", "B", "A - B", "combined spread", "within noise")
    pairs = []
    for i, a in enumerate(spreads):
        for b in spreads[i + 1:]:
            combined = math.hypot(a.std, b.std)
            noise = within_noise(a, b)
            pairs.append((f"{a.agent} ({a.encoder})", f"{b.agent} ({b.encoder})", Cell(f"{a.mean - b.mean:+.3f}", sort=a.mean - b.mean),
                          Cell(f"{combined:.3f}", sort=combined), "within noise" if noise else "no"))
    blocks = [Heading(3, "Seed noise"),
              Paragraph("Each episode ran with several seeds; a seed's rate is over the episodes every seed ran. "
                        "std: sample standard deviation of the per-seed rates. A difference is *within noise* when "
                        "it is no larger than the combined spread sqrt(std_A^2 + std_B^2), what a one-seed "
                        "comparison of the two can move by."),
              Table(head, body, name=f"seeds-{suite}")]
    if pairs:
        blocks.append(Table(pair_head, pairs, name=f"seed-pairs-{suite}"))
    return blocks


_GROUPED_SECTIONS = (
    ("description_kind", "Success by how the goal was named", "description-kinds"),
    ("goal_split", "Success by how seen the goal object is", "goal-splits"),
)
"""Record ``extras`` fields an agent suite's success is split by: (field, heading, table name).
``description_kind``: name, synonym, attribute, function (v2 episodes); ``goal_split``: the goal
object's split group (:data:`sim_envs.scenes.splits.SPLIT_GROUPS`)."""


def _grouped_sections(records, suite: str) -> list:
    """Success per value of each :data:`_GROUPED_SECTIONS` field, per (agent, encoder): one table
    each, left out when no record has the field."""
    from sim_envs.scenes.splits import SPLIT_GROUPS

    blocks = []
    for field, heading, name in _GROUPED_SECTIONS:
        groups = per_category(records, by=field)
        if not groups:
            continue
        present = {k for v in groups.values() for k in v}
        order = [g for g in SPLIT_GROUPS if g in present] if field == "goal_split" else []
        names = order + sorted(present - set(order))
        head = ("agent", "encoder", *names)
        body = [(a, e, *(Cell(f"{v[k][0]:.2f} ({v[k][1]})", sort=v[k][0]) if k in v else "-" for k in names))
                for (_, a, e), v in groups.items()]
        blocks += [Heading(3, heading), Table(head, body, name=f"{name}-{suite}")]
    return blocks


def _path_figures(records, suite: str, w: _Writer) -> list:
    return report_figures.path_figures(records, suite, w)


def _sim_to_sim_section(records) -> list:
    """The same episodes in MuJoCo and PyBullet (a suite beside its ``-pybullet`` variant,
    :mod:`harness.report.sim_to_sim`); empty when no suite ran in both."""
    from harness.report.sim_to_sim import PYBULLET_SUFFIX, sim_to_sim

    if not any(r["suite"].endswith(PYBULLET_SUFFIX) for r in records):
        return []
    try:
        pairs = sim_to_sim(records)
    except HarnessError:
        return []
    head = ("suite", "agent", "perception", "MuJoCo", "PyBullet", "PyBullet - MuJoCo [95% CI]", "McNemar p", "n")
    rows = []
    for s in pairs:
        rates = [s.rate(k) for k in (s.mujoco, s.pybullet)]
        rows.append((f"`{s.suite}`", s.agent, f"{s.encoder} (privileged)" if s.privileged else s.encoder,
                     *(Cell(f"{k}/{s.n}", sort=r[0], interval=r) for k, r in zip((s.mujoco, s.pybullet), rates)),
                     Cell(f"{s.diff:+.2f} [{s.ci[0]:+.2f}, {s.ci[1]:+.2f}]", sort=s.diff), Cell(f"{s.p:.2g}", sort=s.p),
                     Cell(str(s.n), sort=s.n)))
    return [Heading(2, "MuJoCo against PyBullet"),
            Paragraph("The same episodes, agents and perception in both simulators (a suite beside its `-pybullet` "
                      "variant), paired by episode: does a result survive a change of renderer and physics?"),
            Table(head, rows, name="sim-to-sim")]


def _instruct_section(records) -> list:
    """The planner-in-the-loop comparison (:mod:`harness.report.instruct`); empty when no
    instruction suite ran."""
    from harness.report.instruct import KINDS, SUITES, instruct_rows

    if not any(r["suite"] in SUITES for r in records):
        return []
    rows = []
    for s in instruct_rows(records):
        lo, hi = wilson_interval(s.successes, s.n)
        agent = f"{s.agent} (privileged)" if s.privileged else s.agent
        kinds = [Cell(f"{k}/{n}" if n else "-", sort=k / n if n else -1.0) for k, n in (s.by_kind[kind] for kind in KINDS)]
        diff = (Cell(f"{s.diff[0]:+.2f} [{s.diff[1]:+.2f}, {s.diff[2]:+.2f}]", sort=s.diff[0]), Cell(f"{s.diff[3]:.2g}", sort=s.diff[3])
                ) if s.diff else (Cell("", sort=0.0), Cell("", sort=1.0))
        cpu = Cell(f"{s.planner_share:.1%} / {s.listing_share:.1%}", sort=s.planner_share) if s.planner_share is not None \
            else Cell("", sort=0.0)
        rows.append((f"`{s.suite}`", s.encoder, agent, Cell(f"{s.successes}/{s.n}", sort=s.successes / s.n, interval=(
            s.successes / s.n, lo, hi)), *kinds, Cell(f"{s.spl:.2f}", sort=s.spl), *diff, cpu))
    head = ("suite", "perception", "agent", "success", *KINDS, "SPL", "map-planner - generic-planner [95% CI]", "McNemar p",
            "planner / listing CPU")
    return [Heading(2, "A language planner with and without the map"),
            Paragraph("Instructions that name a need, a room or a relation: the same planner and navigator, told what the "
                      "map holds (map-planner) or the instruction alone (generic-planner); the oracle is the upper bound."),
            Table(head, rows, name="instruct")]


def _heatmap_figures(items, w: _Writer) -> list:
    return report_figures.heatmap_figures(items, w)


def build_report(run_dirs_or_records, out_dir: str | os.PathLike, *,
                 title: str = "ConceptFusion harness report",
                 base_dir: str | os.PathLike | None = None, links: ReportLinks | None = None) -> ReportDocument:
    """Build the report as data and write its PNG figures and failure pages into ``out_dir``.

    Arguments as for :func:`write_report`; ``links`` says how pages link replay videos and maps
    (default: relative to ``out_dir``; a bundle copies them in). Raises ``ValueError`` when there
    is nothing to report.
    """
    collected = _collect(run_dirs_or_records, base_dir)
    run_items = list({(label, record_key(r)): (r, b, label) for r, b, label in collected}.values())
    items = list({record_key(r): (r, b) for r, b, _ in collected}.values())
    records = [r for r, _ in items]
    if not records:
        raise ResultsFormatError("write_report: the runs hold no records yet (empty results files?)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    w = _Writer(out)
    links = links or ReportLinks(out)
    rows = summarize(records)
    several_runs = len({label for _, _, label in run_items}) > 1
    answers = suite_answers(records)
    headline = {a.suite: a.metric for a in answers}
    blocks: list = [Heading(2, "Headline"), Cards(tuple(answer_card(a) for a in answers)), *_summary_section(records)]
    suites = sorted({r.suite for r in rows})
    for suite in [a.suite for a in answers] + [s for s in suites if s not in headline]:
        suite_rows = [r for r in rows if r.suite == suite]
        suite_recs = [r for r in records if r["suite"] == suite]
        blocks += [Heading(2, f"Suite `{suite}`", anchor=section_anchor(suite)), *_twin_section(suite_recs, suite, w),
                   _suite_table(suite_rows, suite, _privileged(suite_recs), headline.get(suite))]
        with_success = [r for r in suite_rows if "success" in r.metrics]
        if with_success:
            labels = [f"{r.agent}\n({r.encoder})" for r in with_success]
            stats = [r.metrics["success"] for r in with_success]
            png = report_plots.success_bars(labels, [s.mean for s in stats], [s.low for s in stats],
                                            [s.high for s in stats], title=f"success by agent, suite {suite} (95% CI)")
            blocks.append(Figure(w.figure(f"success_{suite}", png), f"success by agent, {suite}"))
        else:
            w.skip(f"success chart, suite {suite}", "no record has a success metric")
        if several_runs:
            blocks += _runs_side_by_side(run_items, suite)
        blocks += _comparisons(suite_recs, suite, w)
        blocks += _seed_spread_section(suite_recs, suite)
        cats = per_category(suite_recs)
        if cats:
            groups = {f"{a} ({e})": v for (_, a, e), v in cats.items()}
            png = report_plots.category_bars(groups, title=f"success per goal category, suite {suite}")
            blocks += [Heading(3, "Success per goal category"),
                       Figure(w.figure(f"category_{suite}", png), f"success per category, {suite}")]
        else:
            w.skip(f"per-category chart, suite {suite}", "no record has a category and a success value")
        blocks += _grouped_sections(suite_recs, suite)
        path_blocks = _path_figures(suite_recs, suite, w)
        if path_blocks:
            blocks += [Heading(3, "Episodes from above")] + path_blocks
        blocks += failure_section(run_items, suite, links)
        blocks.append(episode_table(run_items, suite, out, show_run=several_runs, links=links))
    blocks += _sim_to_sim_section(records)
    blocks += _instruct_section(records)
    blocks += _heatmap_figures(items, w)
    blocks += [Heading(2, "Skipped"), Bullets(tuple(w.skipped) or ("nothing",))]
    return ReportDocument(title=title, out_dir=out, blocks=blocks, figures=w.figures, items=run_items)


def write_markdown(doc: ReportDocument) -> Path:
    """Write ``doc.out_dir/report.md`` (atomically); returns its path."""
    return atomic_write_text(doc.out_dir / REPORT_FILE, render_markdown(doc))


def write_report(run_dirs_or_records, out_dir: str | os.PathLike, *, title: str = "ConceptFusion harness report",
                 base_dir: str | os.PathLike | None = None) -> Path:
    """Write ``out_dir/report.md`` and its PNG figures; returns the report's path.

    ``run_dirs_or_records``: a run folder or results file, a sequence of them, or a sequence of
    records (dicts). ``base_dir`` resolves relative ``extras.heatmap_npz`` paths of records
    passed directly. A retried episode counts once, with its newest record. Raises
    ``ValueError`` when there is nothing to report.
    """
    return write_markdown(build_report(run_dirs_or_records, out_dir, title=title, base_dir=base_dir))
