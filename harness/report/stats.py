"""Statistics over results records: confidence intervals, per-agent summaries, paired comparisons.

Scoring policy for episodes that did not finish (status ``failed`` or ``timeout``): they count
as unsuccessful (``success`` False) with ``spl`` 0, whatever was recorded; every other metric
is averaged over the episodes that recorded a value for it (a crash usually records none).
Records are first reduced to one per episode key (:func:`harness.runner.results.latest_records`), so a
retried episode counts once, with its newest result.

A metric whose values in a group are all bools is a rate: its interval is Wilson's. Any other
metric is a mean with a percentile bootstrap interval.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from statistics import NormalDist

import numpy as np

from conceptfusion.names import did_you_mean
from harness.runner.results import agent_label, latest_records

__all__ = [
    "DEFAULT_METRICS", "FAILURE_VALUES", "MetricStat", "SummaryRow", "PairedResult", "wilson_interval", "bootstrap_ci",
    "metric_value", "mcnemar_exact", "summarize", "paired_comparison", "per_category", "group_key", "SeedSpread",
    "seed_spread", "within_noise",
]

DEFAULT_METRICS = ("success", "spl")
"""Metrics listed first in a summary; others the records carry follow in name order."""
FAILURE_VALUES = {"success": False, "spl": 0.0}
"""Values a failed or timed-out episode gets for these metrics, whatever it recorded."""


def _z(confidence: float) -> float:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence: expected a value in (0, 1), got {confidence}")
    return NormalDist().inv_cdf(0.5 + confidence / 2)


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion; ``(nan, nan)`` when ``n == 0``.

    (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n), p = successes / n.
    """
    for name, v in (("successes", successes), ("n", n)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"{name}: expected an int, got {type(v).__name__}")
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"expected 0 <= successes <= n, got successes={successes}, n={n}")
    z = _z(confidence)
    if n == 0:
        return (math.nan, math.nan)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return (low, high)


def bootstrap_ci(values, statistic=np.mean, confidence: float = 0.95, n_resamples: int = 2000,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of ``statistic`` over ``values``.

    ``statistic`` is called as ``statistic(samples_rn, axis=1)`` (numpy reductions do this);
    a function without ``axis`` is applied to each resample. Empty input gives ``(nan, nan)``.

    Shape:
        ``values`` (N,) numbers.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"values: expected a 1-D sequence, got shape {x.shape}")
    _z(confidence)
    if n_resamples < 1:
        raise ValueError(f"n_resamples: expected >= 1, got {n_resamples}")
    if x.size == 0:
        return (math.nan, math.nan)
    rng = np.random.default_rng(seed)
    stats = np.empty(n_resamples)
    chunk = max(1, 2_000_000 // x.size)
    for start in range(0, n_resamples, chunk):
        stop = min(n_resamples, start + chunk)
        samples = x[rng.integers(0, x.size, size=(stop - start, x.size))]
        try:
            stats[start:stop] = statistic(samples, axis=1)
        except TypeError:
            stats[start:stop] = [statistic(s) for s in samples]
    alpha = (1 - confidence) / 2
    low, high = np.quantile(stats, [alpha, 1 - alpha])
    return (float(low), float(high))


def metric_value(record: dict, metric: str):
    """A record's value for ``metric`` under the failure policy; None when it has none."""
    if record.get("status") != "ok" and metric in FAILURE_VALUES:
        return FAILURE_VALUES[metric]
    value = (record.get("metrics") or {}).get(metric)
    if value is None or isinstance(value, bool):
        return value
    value = float(value)
    return value if math.isfinite(value) else None


def group_key(record: dict) -> tuple[str, str, str]:
    """``(suite, agent label, encoder)`` of a record."""
    return (record["suite"], agent_label(record["agent"], record.get("agent_kwargs") or {}), record["encoder"])


@dataclass(frozen=True)
class MetricStat:
    """Mean of one metric over a group, with its interval.

    ``rate`` is True for a bool metric (Wilson interval), False for a bootstrap mean.
    """

    mean: float
    low: float
    high: float
    n: int
    rate: bool


def _metric_stat(values: list, confidence: float, seed: int) -> MetricStat | None:
    if not values:
        return None
    if all(isinstance(v, bool) for v in values):
        k = sum(values)
        low, high = wilson_interval(k, len(values), confidence)
        return MetricStat(k / len(values), low, high, len(values), True)
    x = np.asarray(values, dtype=np.float64)
    low, high = bootstrap_ci(x, confidence=confidence, seed=seed)
    return MetricStat(float(x.mean()), low, high, int(x.size), False)


@dataclass(frozen=True)
class SummaryRow:
    """One (suite, agent, encoder) group of episodes.

    ``n`` episodes, of which ``n_failed`` crashed and ``n_timeout`` ran out of time;
    ``metrics`` maps a metric name to its :class:`MetricStat` (absent when no episode has it);
    ``wall_s`` is the mean wall time per episode (NaN when none was recorded).
    """

    suite: str
    agent: str
    encoder: str
    n: int
    n_failed: int
    n_timeout: int
    wall_s: float
    metrics: dict[str, MetricStat] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Flat dict: the group fields, then ``<metric>``, ``<metric>_low``, ``<metric>_high``, ``<metric>_n``."""
        out = {k: getattr(self, k) for k in ("suite", "agent", "encoder", "n", "n_failed", "n_timeout", "wall_s")}
        for name, s in self.metrics.items():
            out.update({name: s.mean, f"{name}_low": s.low, f"{name}_high": s.high, f"{name}_n": s.n})
        return out


def _metric_names(records, metrics) -> list[str]:
    if metrics is not None:
        if isinstance(metrics, str):
            raise TypeError(f"metrics: expected a sequence of names, got the string {metrics!r}")
        return list(metrics)
    seen = {m for r in records for m in (r.get("metrics") or {})}
    return [m for m in DEFAULT_METRICS] + sorted(seen - set(DEFAULT_METRICS))


def summarize(records, metrics=None, *, confidence: float = 0.95, seed: int = 0) -> list[SummaryRow]:
    """One :class:`SummaryRow` per (suite, agent label, encoder), sorted by that key.

    ``metrics``: names to summarise; default :data:`DEFAULT_METRICS` then every other metric
    the records carry. See the module docstring for how failed episodes are scored.
    """
    recs = latest_records(records)
    names = _metric_names(recs, metrics)
    groups: dict[tuple, list[dict]] = {}
    for r in recs:
        groups.setdefault(group_key(r), []).append(r)
    rows = []
    for key in sorted(groups):
        group = groups[key]
        stats = {}
        for name in names:
            values = [v for v in (metric_value(r, name) for r in group) if v is not None]
            s = _metric_stat(values, confidence, seed)
            if s is not None:
                stats[name] = s
        walls = [float(r["timings"]["wall_s"]) for r in group if "wall_s" in (r.get("timings") or {})]
        rows.append(SummaryRow(
            *key, n=len(group), n_failed=sum(r["status"] == "failed" for r in group),
            n_timeout=sum(r["status"] == "timeout" for r in group),
            wall_s=float(np.mean(walls)) if walls else math.nan, metrics=stats,
        ))
    return rows


@dataclass(frozen=True)
class PairedResult:
    """Agent A against agent B on the episodes both ran (same suite, episode id and seed).

    ``mean_diff`` is mean(A - B) with a paired bootstrap interval ``[ci_low, ci_high]``. For a
    bool metric, ``a_only``/``b_only`` count the discordant pairs (only A / only B succeeded) and
    ``p_value`` is the exact two-sided McNemar (binomial) test; for a continuous metric it is the
    Wilcoxon signed-rank test (1.0 when every difference is zero).
    """

    agent_a: str
    agent_b: str
    metric: str
    suite: str | None
    encoder_a: str | None
    encoder_b: str | None
    n_pairs: int
    mean_a: float
    mean_b: float
    mean_diff: float
    ci_low: float
    ci_high: float
    p_value: float
    binary: bool
    a_only: int | None = None
    b_only: int | None = None

    def as_dict(self) -> dict:
        """All fields as a plain dict."""
        return asdict(self)


def mcnemar_exact(a_only: int, b_only: int) -> float:
    """Exact two-sided McNemar p-value: 2 P(X <= min) for X ~ Binomial(a_only + b_only, 1/2), capped at 1."""
    n = a_only + b_only
    if n == 0:
        return 1.0
    k = min(a_only, b_only)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0**n
    return min(1.0, 2.0 * tail)


def _agent_values(records, label, suite, encoder, metric, labels_seen) -> dict:
    out: dict[tuple, tuple] = {}
    for r in records:
        s, a, e = group_key(r)
        if a != label or (suite is not None and s != suite) or (encoder is not None and e != encoder):
            continue
        pair_key = (s, r["episode_id"], r["seed"])
        if pair_key in out and out[pair_key][0] != e:
            raise ValueError(f"agent {label!r} ran episode {r['episode_id']!r} (seed {r['seed']}) with several "
                             f"encoders ({out[pair_key][0]!r}, {e!r}); pass encoder= to choose one")
        out[pair_key] = (e, metric_value(r, metric))
    if not out:
        raise ValueError(f"no records of agent {label!r} (suite={suite!r}, encoder={encoder!r}); agents present: "
                         f"{sorted(labels_seen)}" + did_you_mean(label, sorted(labels_seen), cutoff=0.3))
    return {k: v for k, (_, v) in out.items()}


def paired_comparison(records, agent_a: str, agent_b: str, metric: str = "success", *, suite: str | None = None,
                      encoder: str | None = None, encoder_b: str | None = None, confidence: float = 0.95,
                      seed: int = 0) -> PairedResult:
    """Compare two agent labels episode by episode (pairs by suite, episode id and seed).

    ``encoder`` selects agent A's encoder and, unless ``encoder_b`` is given, agent B's too.
    Episodes where either agent has no value for ``metric`` are left out. ``ValueError`` when an
    agent has no records or no episode pairs up.
    """
    recs = latest_records(records)
    labels = {group_key(r)[1] for r in recs}
    enc_b = encoder if encoder_b is None else encoder_b
    va = _agent_values(recs, agent_a, suite, encoder, metric, labels)
    vb = _agent_values(recs, agent_b, suite, enc_b, metric, labels)
    keys = sorted(k for k in set(va) & set(vb) if va[k] is not None and vb[k] is not None)
    if not keys:
        raise ValueError(f"no episodes pair up between {agent_a!r} ({len(va)} episodes) and {agent_b!r} "
                         f"({len(vb)} episodes) on metric {metric!r}: pairs need the same suite, episode id and "
                         "seed, and a value for the metric from both")
    a = [va[k] for k in keys]
    b = [vb[k] for k in keys]
    binary = all(isinstance(v, bool) for v in a + b)
    xa, xb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    diff = xa - xb
    low, high = bootstrap_ci(diff, confidence=confidence, seed=seed)
    a_only = b_only = None
    if binary:
        a_only, b_only = int(np.sum(diff > 0)), int(np.sum(diff < 0))
        p = mcnemar_exact(a_only, b_only)
    elif np.all(diff == 0):
        p = 1.0
    else:
        from scipy.stats import wilcoxon

        p = float(wilcoxon(diff).pvalue)
    return PairedResult(agent_a, agent_b, metric, suite, encoder, enc_b, len(keys), float(xa.mean()),
                        float(xb.mean()), float(diff.mean()), low, high, float(p), binary, a_only, b_only)


def per_category(records, metric: str = "success", *, by: str = "category") -> dict[tuple[str, str, str], dict[str, tuple[float, int]]]:
    """Mean of ``metric`` per goal category: ``{(suite, agent, encoder): {category: (mean, n)}}``.

    ``by``: ``"category"`` (the record's goal category) or the name of an ``extras`` field to
    group by instead (``"description_kind"``: how the goal was named). Records without that field
    or without a value for the metric are left out.
    """
    sums: dict[tuple, dict[str, list[float]]] = {}
    for r in latest_records(records):
        cat = r.get("category") if by == "category" else (r.get("extras") or {}).get(by)
        value = metric_value(r, metric)
        if cat is None or value is None:
            continue
        sums.setdefault(group_key(r), {}).setdefault(str(cat), []).append(float(value))
    return {key: {c: (float(np.mean(v)), len(v)) for c, v in sorted(cats.items())} for key, cats in sorted(sums.items())}


@dataclass(frozen=True)
class SeedSpread:
    """How much one (suite, agent label, encoder) group's mean moves between seeds.

    Only episodes run with every seed of the group count (so each seed's rate is over the same
    episodes). ``rates`` holds each seed's mean of the metric over them; ``mean`` is their
    mean, ``std`` their sample standard deviation (NaN with one seed), ``low``/``high`` their
    min and max.
    """

    suite: str
    agent: str
    encoder: str
    seeds: tuple[int, ...]
    episodes: int
    """Episodes run with every seed (each seed's rate is over these)."""
    rates: tuple[float, ...]
    mean: float
    std: float
    low: float
    high: float


def seed_spread(records, metric: str = "success") -> list[SeedSpread]:
    """One :class:`SeedSpread` per (suite, agent label, encoder) group, sorted by that key; groups
    whose records have no value for ``metric`` are left out. See the module docstring for how
    failed episodes are scored.

    Shape:
        each ``rates`` has one entry per seed of ``seeds``.
    """
    by_group: dict[tuple, dict[int, dict[str, float]]] = {}
    for r in latest_records(records):
        v = metric_value(r, metric)
        if v is None:
            continue
        by_group.setdefault(group_key(r), {}).setdefault(int(r["seed"]), {})[r["episode_id"]] = float(v)
    out = []
    for key in sorted(by_group):
        per_seed = by_group[key]
        seeds = tuple(sorted(per_seed))
        common = set.intersection(*(set(per_seed[s]) for s in seeds))
        if not common:
            continue
        rates = tuple(float(np.mean([per_seed[s][e] for e in sorted(common)])) for s in seeds)
        std = float(np.std(rates, ddof=1)) if len(rates) > 1 else math.nan
        out.append(SeedSpread(*key, seeds=seeds, episodes=len(common), rates=rates, mean=float(np.mean(rates)), std=std,
                              low=min(rates), high=max(rates)))
    return out


def within_noise(a: SeedSpread, b: SeedSpread) -> bool | None:
    """Whether the difference of two groups' seed means is no larger than their combined
    between-seed spread, ``sqrt(std_a^2 + std_b^2)`` (what a one-seed comparison of the two can
    move by); None when either has a single seed (no spread to compare with)."""
    if len(a.seeds) < 2 or len(b.seeds) < 2:
        return None
    return abs(a.mean - b.mean) <= math.hypot(a.std, b.std)
