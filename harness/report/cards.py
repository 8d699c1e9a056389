"""The report's first screen: per suite, the question it answers and the answer, from the records.

A suite's question, headline metric and declared baseline are set where the suite is defined
(:class:`harness.runner.suites.Suite`: ``question``, ``headline_metric``, ``baseline``,
``verdicts``); a suite the harness does not know (a user's own) gets a generic question and is
ranked by ``success`` when its records have it, else by the first metric of its first record.

Per suite (:func:`suite_answer`):

- **best**: the (agent, encoder) group with the highest mean of the headline metric (a tie goes
  to a map agent: one with a matched twin, or whose records say it uses a map; higher is
  better), among the groups that read no ground truth; a group with ``extras.privileged`` is only
  best when every group is privileged, and is then marked (an oracle, privileged with no
  perception at all, only when nothing else ran: it is an upper bound). A privileged group that scores higher
  than the best is named in the card's note, marked, never ranked.
- **compared with**: the matched map-free twin when one ran (a group whose records name the map
  agent in ``extras.twin_of``; the pair holding the best agent, else the pair whose map agent
  scores highest); otherwise the suite's declared ``baseline`` agent against the best other agent;
  otherwise nothing (the card shows the best figure with its interval).
- **difference**: :func:`harness.report.stats.paired_comparison` of the two on the headline metric
  (episodes paired by suite, episode id and seed; bootstrap 95% interval; exact McNemar p for
  rates, Wilcoxon signed-rank otherwise).
- **verdict**: the suite's first verdict word ("map helps") when the interval lies above 0, its
  second ("map hurts") when below, "no detectable difference" when it holds 0; with fewer than
  :data:`MIN_PAIRS` pairs "too few to tell" (a bootstrap interval over a handful of episodes is
  far too narrow to decide on).

Everything is recomputed from the records every time; nothing is read back from a file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from harness.report.document import Card, Cards
from harness.report.labels import metric_title
from harness.report.stats import MetricStat, PairedResult, group_key, paired_comparison, summarize

__all__ = ["GENERIC_QUESTION", "MIN_PAIRS", "SuiteAnswer", "suite_answer", "suite_answers", "answer_card", "headline_cards",
           "section_anchor"]

GENERIC_QUESTION = "How do the agents compare?"
"""The question of a suite that declares none."""
MIN_PAIRS = 10
"""Fewest paired episodes a verdict is given on."""
_SAME = "no detectable difference"
_FEW = "too few to tell"
_TWIN_ROLE = "matched map-free twin"
_BASELINE_ROLE = "suite baseline"

Group = tuple[str, str]
"""(agent label, encoder)."""


@dataclass(frozen=True)
class _Spec:
    question: str
    headline_metric: str
    baseline: str
    verdicts: tuple[str, str]
    rank: int
    """Position among the harness's suites (unknown suites after them)."""


def _spec(suite: str) -> _Spec:
    from harness.runner.suites import SUITES  # heavy (scene and planner modules); only when a report is built

    names = list(SUITES)
    s = SUITES.get(suite)
    if s is None:
        return _Spec(GENERIC_QUESTION, "", "", ("map helps", "map hurts"), len(names))
    return _Spec(s.question or GENERIC_QUESTION, s.headline_metric, s.baseline, tuple(s.verdicts), names.index(suite))


@dataclass(frozen=True)
class SuiteAnswer:
    """The numbers behind one suite's card."""

    suite: str
    question: str
    metric: str
    """The headline metric (a key of the records' ``metrics``)."""
    best: Group
    best_stat: MetricStat
    privileged: frozenset
    """The groups of the suite that read ground truth (``extras.privileged``)."""
    compared: Group | None = None
    """Agent A of the comparison (usually ``best``); None: no comparison."""
    baseline: Group | None = None
    """Agent B of the comparison."""
    role: str = ""
    """What the baseline is: ``matched map-free twin`` or ``suite baseline``."""
    comparison: PairedResult | None = None
    """A - B on the headline metric, paired per episode."""
    verdict: str = ""
    tone: str = ""
    """``better``, ``same``, ``worse``, or empty (no verdict)."""
    note: str = ""
    rank: tuple = ()
    """Sort key of the card: twin comparisons first, then baselines, then the rest."""


def _headline_metric(records: list[dict], declared: str) -> str | None:
    present = [m for r in records for m in (r.get("metrics") or {})]
    if declared and declared in present:
        return declared
    if "success" in present:
        return "success"
    return present[0] if present else None


def headline_metric(records, suite: str) -> str | None:
    """The metric a suite is judged by, for its card and its episode rows: the one the suite
    declares (:attr:`harness.runner.suites.Suite.headline_metric`) when its records have it,
    else ``success``, else the records' first metric; None when they have none."""
    return _headline_metric([r for r in records if r.get("suite") == suite], _spec(suite).headline_metric)


def _twin_pairs(records: list[dict], groups) -> list[tuple[Group, Group]]:
    """(map agent, its twin) for the twins whose records name a map agent that ran (same encoder)."""
    out = set()
    for r in records:
        of = (r.get("extras") or {}).get("twin_of")
        if isinstance(of, str) and of:
            _, agent, enc = group_key(r)
            if (of, enc) in groups and (agent, enc) in groups:
                out.add(((of, enc), (agent, enc)))
    return sorted(out)


def _verdict(res: PairedResult, verdicts: tuple[str, str]) -> tuple[str, str, str]:
    """(verdict, tone, note) of a comparison."""
    if res.n_pairs < MIN_PAIRS:
        return _FEW, "", f"{res.n_pairs} pairs: too few for a verdict (it needs {MIN_PAIRS})"
    if res.ci_low > 0:
        return verdicts[0], "better", ""
    if res.ci_high < 0:
        return verdicts[1], "worse", ""
    return _SAME, "same", ""


def suite_answer(records: list[dict], suite: str) -> SuiteAnswer | None:
    """The answer of ``suite`` from its records (records of other suites are ignored); None when
    no record of it has a metric."""
    recs = [r for r in records if r.get("suite") == suite]
    spec = _spec(suite)
    metric = _headline_metric(recs, spec.headline_metric)  # headline_metric(), with the spec at hand
    if metric is None:
        return None
    stats = {(row.agent, row.encoder): row.metrics[metric] for row in summarize(recs, (metric,)) if metric in row.metrics}
    if not stats:
        return None
    privileged = frozenset(group_key(r)[1:] for r in recs if (r.get("extras") or {}).get("privileged") is True)
    public = [g for g in stats if g not in privileged]
    # an oracle (privileged, no perception: it reads the goal itself) is an upper bound, ranked last
    oracles = {g for g in stats if g in privileged and g[1] == "none"}
    perceiving = [g for g in stats if g not in oracles]
    pairs = _twin_pairs(recs, stats)
    # a tie goes to a map agent (one with a twin, or that says it uses a map): the question is about the map
    mapping = {m for m, _ in pairs} | {group_key(r)[1:] for r in recs if (r.get("extras") or {}).get("uses_map") is True}
    by_score = sorted(public or perceiving or stats, key=lambda g: (-stats[g].mean, g not in mapping, g))
    best = by_score[0]
    notes = [f"{_label(g, privileged)} scores {stats[g].mean:.2f}, not ranked: it reads ground truth a robot does not have"
             for g in sorted(stats, key=lambda g: -stats[g].mean) if public and g in privileged and stats[g].mean > stats[best].mean]
    kind = 2
    compared = baseline = None
    role = ""
    fair = [p for p in pairs if not (set(p) & privileged)] or pairs
    if fair:
        holding = [p for p in fair if best in p]
        compared, baseline = holding[0] if holding else max(fair, key=lambda p: (stats[p[0]].mean, p))
        role, kind = _TWIN_ROLE, 0
    elif spec.baseline:
        bases = [g for g in stats if g[0] == spec.baseline]
        others = [g for g in by_score if g[0] != spec.baseline and g not in oracles]
        if bases and others:
            compared = others[0]
            baseline = next((g for g in bases if g[1] == compared[1] and g not in privileged),
                            next((g for g in bases if g not in privileged), bases[0]))
            role, kind = _BASELINE_ROLE, 1
    answer = dict(suite=suite, question=spec.question, metric=metric, best=best, best_stat=stats[best], privileged=privileged,
                  rank=(kind, spec.rank, suite))
    if compared is None:
        return SuiteAnswer(**answer, note="; ".join(notes))
    try:
        res = paired_comparison(recs, compared[0], baseline[0], metric, suite=suite, encoder=compared[1], encoder_b=baseline[1])
    except ValueError as exc:
        return SuiteAnswer(**answer, compared=compared, baseline=baseline, role=role,
                           note="; ".join(notes + [f"no comparison: {exc}"]))
    verdict, tone, why = _verdict(res, spec.verdicts)
    return SuiteAnswer(**answer, compared=compared, baseline=baseline, role=role, comparison=res, verdict=verdict, tone=tone,
                       note="; ".join(notes + ([why] if why else [])))


def suite_answers(records: list[dict]) -> list[SuiteAnswer]:
    """:func:`suite_answer` of every suite of the records, in card order: suites answered against
    a matched twin first, then those against a declared baseline, then the rest (each in the
    order the harness defines its suites, unknown ones by name)."""
    answers = [suite_answer(records, s) for s in sorted({r["suite"] for r in records})]
    return sorted((a for a in answers if a is not None), key=lambda a: a.rank)


def section_anchor(suite: str) -> str:
    """The HTML ``id`` of a suite's section, which its card links to."""
    return f"section-{suite}"


def _label(group: Group, privileged, encoder_shown: bool = True) -> str:
    agent, enc = group
    text = f"{agent} ({enc})" if encoder_shown else agent
    return text + (" (privileged)" if group in privileged else "")


def _fmt(x: float) -> str:
    return f"{x:.0f}" if abs(x) >= 100 else f"{x:.2f}"


def _p(p: float) -> str:
    return "p < 0.001" if p < 0.001 else f"p {p:.2g}"


def answer_card(a: SuiteAnswer) -> Card:
    """The display text of one answer."""
    s = a.best_stat
    interval = "" if math.isnan(s.low) else f" [{_fmt(s.low)}, {_fmt(s.high)}]"
    bar = (s.mean, s.low, s.high) if not math.isnan(s.low) and 0 <= s.low <= s.high <= 1 else None
    card = dict(title=a.suite, question=a.question, best=_label(a.best, a.privileged),
                figure=f"{metric_title(a.metric)} {_fmt(s.mean)}{interval}, n {s.n}", note=a.note,
                href=f"#{section_anchor(a.suite)}", interval=bar)
    if a.compared is None:
        return Card(**card)
    same_enc = a.baseline[1] == a.best[1]
    base = f"{_label(a.baseline, a.privileged, not same_enc)} ({a.role})"
    res = a.comparison
    if res is None:
        return Card(**card, against=base)
    lead = "" if a.compared == a.best else f"{_label(a.compared, a.privileged, a.compared[1] != a.best[1])} {_fmt(res.mean_a)} against "
    test = "exact McNemar" if res.binary else "Wilcoxon signed-rank"
    return Card(**card, against=f"{lead}{base} {_fmt(res.mean_b)}",
                difference=f"{res.mean_diff:+.2f} [{res.ci_low:+.2f}, {res.ci_high:+.2f}]",
                test=f"{_p(res.p_value)} ({test}), {res.n_pairs} pairs", verdict=a.verdict, tone=a.tone)


def headline_cards(records: list[dict]) -> Cards:
    """The first screen of a report: a :class:`~harness.report.document.Card` per suite of the
    records, in :func:`suite_answers` order."""
    return Cards(tuple(answer_card(a) for a in suite_answers(records)))
