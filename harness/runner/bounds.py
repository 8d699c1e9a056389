"""Success bounds of the regression suites, with statistical power, derived from recorded calibration runs.

A regression suite (:mod:`harness.runner.suites`: ``regression-rearrange``,
``regression-rearrange-embedded``, ``regression-search``, and the headline gate
``regression-rearrange-v2``, ``regression-search-v2``, and the search gate's PyBullet slice
``regression-search-v2-pybullet``) pins the first episodes of an episode
file and holds every agent it runs to a *lower bound* on its success rate (the random agents to an
*upper bound*: a broken success function shows as a random agent succeeding). No bound is set by
hand: this module derives each one from a recorded **calibration run**, the same agents with the
same settings (environment size, scan frames, pinned perception, seed) over *other* episodes drawn
from the same generators (the suite's ``calibration_file``: ``scenes/calibration/``, made by
``python -m scenes.make_calibration``, for the v1 suites; ``scenes/gate-v2/``, made by ``python -m
scenes.make_gate_v2``, for the headline gate and its PyBullet slice; not one of them is a regression episode, so a bound
is never fitted to the episodes it checks).

**Procedure** (:func:`derive_bound`), for an agent that succeeded on ``k`` of ``m`` calibration
episodes, calibrated rate ``p = k / m``, confidence ``1 - a`` (:data:`CONFIDENCE`, a = 0.05):

- *Lower bound* for ``n`` regression episodes: the largest count ``c`` with ``P(Bin(n, p) < c) <= a``;
  the lower bound is ``c / n`` and the check fails when the run's rate is below it. Equivalently, the
  check fails exactly when the exact one-sided ``1 - a`` Clopper-Pearson upper bound of the run's
  success rate falls below the calibrated rate ``p``: the run shows, at that confidence, that the
  agent got worse than calibrated (:func:`clopper_pearson`; the test suite checks the two agree).
- *Upper bound* (random agents): the smallest ``c`` with ``P(Bin(n, p) > c) <= a``; the check fails
  when the rate is above ``c / n`` (the Clopper-Pearson lower bound of the run's rate rises above
  ``p``).
- *Power* (:func:`detection_probability`): the exact binomial probability that the check fails
  when the agent's true rate has dropped by :data:`DROP` (15 points) from ``p`` (an upper bound: risen by
  15 points), ``P(Bin(n, p - 0.15) < c)``. The episode count ``n`` is the smallest that reaches
  :data:`POWER` (80%) and whose bound can fail at all (``c >= 1`` for a lower bound, ``c < n`` for an
  upper bound), within the suite's CI budget :data:`MAX_EPISODES` and the episodes its file holds;
  where the target needs more, ``n`` is the smallest count with the highest detection
  probability the budget allows, and that probability is recorded (``power_met`` false) instead
  of being claimed. An agent that almost never succeeds cannot be given a lower bound that can fail
  on few episodes: at a calibrated rate ``p`` even a lower bound of one success needs ``n`` with
  ``(1 - p)^n <= a`` (149 episodes at p = 0.02, 299 at p = 0.01). ``frame-searcher`` (oracle
  perception, 1 of 100 calibration episodes) is such an agent: its lower bound is 0 (``can_fail``
  false) and it runs one pinned episode, which guards only against crashes (the check fails any
  crashed episode, ``harness.commands``), not against it finding goals less often.
- *False alarms*: ``false_alarm`` is the probability that an unchanged agent whose true rate is
  exactly ``p`` fails the check (at most ``a`` by construction); ``false_alarm_expected`` averages
  it over what the calibration leaves uncertain about the rate (Jeffreys posterior
  Beta(k + 1/2, m - k + 1/2), i.e. the beta-binomial predictive of the regression count), so it
  is the chance that a calibration plus a regression run of an unchanged agent disagree; it is
  larger than ``a`` because ``p`` is itself an estimate from ``m`` episodes. With many bounds in
  the gate, the chance that *some* bound fails for unchanged agents is far larger than any one
  bound's (``false_alarm_any_expected`` in the bounds file): with per-bound 95% counts it was
  about 45% for the ten v1 bounds, the price of catching a 15-point drop with 80% probability per
  agent on at most 100 episodes; hence the family-wise counts below.

All of it is exact binomial (or beta-binomial) arithmetic from :mod:`scipy.stats`, never a
normal approximation. The regression episodes are pinned and the agents deterministic, so a run
of unchanged code always gives the same verdict (a false alarm shows the day the bounds are
calibrated), while a change that leaves an agent's rate as it was still reshuffles which
episodes it solves, and then fails a bound with the probabilities above (per-bound counts gave
such a false alarm on the gate's first run; see docs/measurement-history.md). The gate
therefore sets every count at the family-wise level (:data:`FAMILY_ALARM`,
:func:`family_confidence`: the whole gate fails for unchanged agents at their calibrated rates
with probability at most 5%), keeping the episode counts chosen for per-bound power; the
detection probabilities recorded are those of the family-wise counts (``power_met`` false for
most agents: 0.36-0.57 on the v1 suites and the v2 pushers, about 0.1 for the v2 navigators,
whose 34-36 pinned searches at a calibrated rate near one half catch a fall of 25 points half
the time and one of 30 points three times in four: they guard against a broken pipeline, not a
small slip).

**Files.** The calibration records (``harness/data/bounds/<suite>.jsonl``, results records as
the runner writes them, less the per-step ``extras.path_xy`` traces) and the bounds
(:data:`~harness.runner.suites.BOUNDS_FILE`, read by the suites) are written only by::

    cfharness develop bounds --calibrate [--suite NAME ...]   # run, then write records + bounds
    cfharness develop bounds --check                          # recompute from the records, compare

``--check`` recomputes every bound from the committed records with this code, checks that the
records cover every agent and calibration episode with the suite's current settings, and exits 1
when anything differs from the committed bounds file.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import uuid
from dataclasses import dataclass
from pathlib import Path

from scipy import stats

from conceptfusion.errors import HarnessError
from conceptfusion.io_utils import atomic_write_text, read_json_file
from conceptfusion.names import unknown_name_error
from harness.report.stats import metric_value
from harness.runner.results import latest_records, load_results
from harness.runner.run import RunConfig, episode_jobs, run_missing_jobs
from harness.runner.suites import BOUNDS_FILE, SUITES, Suite, suite_encoder, suite_episodes, suite_over
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes
from sim_envs.scenes.sealed import refuse_sealed_episodes

__all__ = [
    "CONFIDENCE", "DROP", "POWER", "MAX_EPISODES", "UPPER_BOUND_AGENTS", "BOUNDS_FORMAT", "BOUNDS_VERSION", "RECORDS_DIR",
    "Bound", "lower_count", "upper_count", "detection_probability", "false_alarm_probability",
    "expected_false_alarm", "clopper_pearson", "derive_bound", "regression_suites", "calibration_suite",
    "records_file", "load_calibration", "derive_suite", "derive_bounds", "calibrate", "check", "replay_sample",
    "markdown_table", "main",
]

CONFIDENCE = 0.95
"""Confidence of the one-sided binomial bounds: an agent at its calibrated rate fails its check
with probability at most ``1 - CONFIDENCE``."""
DROP = 0.15
"""The change in success rate (15 points) that the check must catch with probability :data:`POWER`."""
POWER = 0.80
FAMILY_ALARM = 0.05
"""The chance, at most, that the whole gate (every bound of every regression suite) fails for
unchanged agents at their calibrated rates: each bound's count is set at the Sidak level
``1 - (1 - FAMILY_ALARM) ** (1 / bounds)`` (the episode counts stay those chosen for per-bound
power at :data:`CONFIDENCE`, so the recorded detection probabilities are those of the lower
family-wise counts)."""
"""Target probability of catching a drop of :data:`DROP` (a rise, for an upper bound)."""
MAX_EPISODES = {"regression-rearrange": 100, "regression-rearrange-embedded": 100, "regression-search": 50,
                "regression-rearrange-v2": 80, "regression-search-v2": 36, "regression-search-v2-pybullet": 36}
"""Most pinned episodes an agent may run per regression suite (CI budget, and for v1 search and
v2 rearrangement all the pinned episodes): the power computation chooses within it. A v2 search
episode takes about 11 s with embedded perception, so ``regression-search-v2`` holds each
navigator to at most 36 (half the gate's 72 pinned searches, about 7 minutes of the gate on two
cores); its PyBullet slice ``regression-search-v2-pybullet`` (oracle-open perception, a few
seconds an episode) runs at most the same 36 searches per agent."""
UPPER_BOUND_AGENTS = frozenset({"random-pusher", "random-walker"})
"""Agents held to an upper bound instead of a lower bound."""
BOUNDS_FORMAT = "cf-bounds"
BOUNDS_VERSION = 1
RECORDS_DIR = BOUNDS_FILE.parent
"""Folder of the committed calibration records and the bounds file."""
_DROPPED_EXTRAS = ("path_xy",)
"""Per-step traces left out of the committed records (the outcome fields are kept whole)."""


# ------------------------------------------------------------------------------ the statistics
def _check_counts(k: int, n: int, what: str = "successes") -> None:
    for name, v in ((what, k), ("n", n)):
        if isinstance(v, bool) or not isinstance(v, int):
            raise TypeError(f"{name}: expected an int, got {type(v).__name__} {v!r}")
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"expected 0 <= {what} <= n and n >= 1, got {what}={k}, n={n}")


def _check_rate(p: float) -> None:
    if not (isinstance(p, (int, float)) and not isinstance(p, bool) and 0.0 <= p <= 1.0):
        raise ValueError(f"rate: expected a number in [0, 1], got {p!r}")


def lower_count(rate: float, n: int, confidence: float = CONFIDENCE) -> int:
    """The largest ``c`` in ``0..n`` with ``P(Bin(n, rate) < c) <= 1 - confidence``: a run of ``n``
    episodes fails a lower bound when it has fewer than ``c`` successes."""
    _check_rate(rate)
    _check_counts(0, n)
    alpha = 1.0 - confidence
    c = 0
    while c < n and stats.binom.cdf(c, n, rate) <= alpha:  # P(K <= c) = P(K < c + 1)
        c += 1
    return c


def upper_count(rate: float, n: int, confidence: float = CONFIDENCE) -> int:
    """The smallest ``c`` in ``0..n`` with ``P(Bin(n, rate) > c) <= 1 - confidence``: a run of ``n``
    episodes fails an upper bound when it has more than ``c`` successes."""
    _check_rate(rate)
    _check_counts(0, n)
    alpha = 1.0 - confidence
    c = 0
    while c < n and stats.binom.sf(c, n, rate) > alpha:  # sf(c) = P(K > c)
        c += 1
    return c


def _fails(kind: str, count: int, n: int, rate: float) -> float:
    """P(the check fails) for a true rate ``rate``, exact binomial."""
    if kind == "lower":
        return float(stats.binom.cdf(count - 1, n, rate)) if count > 0 else 0.0
    return float(stats.binom.sf(count, n, rate))


def detection_probability(kind: str, count: int, n: int, rate: float, drop: float = DROP) -> float:
    """Probability that the check (``kind`` ``"lower"`` or ``"upper"`` at ``count`` of ``n``)
    fails when the true rate has moved ``drop`` from ``rate`` the wrong way (down for a lower bound, up
    for an upper bound; clipped to [0, 1])."""
    moved = max(rate - drop, 0.0) if kind == "lower" else min(rate + drop, 1.0)
    return _fails(kind, count, n, moved)


def false_alarm_probability(kind: str, count: int, n: int, rate: float) -> float:
    """Probability that an agent whose true rate is ``rate`` fails the check."""
    return _fails(kind, count, n, rate)


def expected_false_alarm(kind: str, count: int, n: int, k: int, m: int) -> float:
    """Probability that an unchanged agent fails the check, averaged over the calibration's
    uncertainty about its rate (``k`` of ``m``; Jeffreys posterior, beta-binomial predictive)."""
    a, b = k + 0.5, m - k + 0.5
    if kind == "lower":
        return float(stats.betabinom.cdf(count - 1, n, a, b)) if count > 0 else 0.0
    return float(stats.betabinom.sf(count, n, a, b))


def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE, side: str = "upper") -> float:
    """One-sided exact (Clopper-Pearson) bound of a binomial rate from ``k`` of ``n``: ``side``
    ``"upper"`` or ``"lower"``, at ``confidence``."""
    _check_counts(k, n)
    alpha = 1.0 - confidence
    if side == "upper":
        return 1.0 if k == n else float(stats.beta.ppf(1 - alpha, k + 1, n - k))
    if side == "lower":
        return 0.0 if k == 0 else float(stats.beta.ppf(alpha, k, n - k + 1))
    raise ValueError(f"side: expected 'upper' or 'lower', got {side!r}")


@dataclass(frozen=True)
class Bound:
    """One agent's lower or upper bound in one regression suite, and how it was derived.

    The check (``harness.commands``) fails when the agent's success rate over its ``episodes``
    pinned episodes is below ``value`` (a lower bound) or above it (an upper bound);
    ``value = count / episodes``.
    """

    agent: str
    bound: str
    """``"lower"`` or ``"upper"``."""
    value: float
    count: int
    """Successes at the bound: a lower bound fails below ``count`` successes, an upper bound above."""
    episodes: int
    """Pinned regression episodes the agent runs (the first ``episodes`` of the suite's file)."""
    calibration_successes: int
    calibration_episodes: int
    detection: float
    """Probability that a drop (rise) of :data:`DROP` from the calibrated rate fails the check."""
    power_met: bool
    """Whether ``detection`` reaches :data:`POWER` (False: the CI budget was too small)."""
    can_fail: bool
    """Whether any outcome of the run fails the check (a lower bound of 0 cannot)."""
    false_alarm: float
    """P(check fails) for an agent exactly at the calibrated rate (<= 1 - :data:`CONFIDENCE`)."""
    false_alarm_expected: float
    """P(check fails) for an unchanged agent, over the calibration's uncertainty (beta-binomial)."""

    @property
    def calibration_rate(self) -> float:
        return self.calibration_successes / self.calibration_episodes

    def as_json(self) -> dict:
        """The bounds-file entry (probabilities rounded to 4 digits; ``value`` exact)."""
        return {
            "bound": self.bound, "value": self.value, "count": self.count, "episodes": self.episodes,
            "calibration": {"successes": self.calibration_successes, "episodes": self.calibration_episodes,
                            "rate": round(self.calibration_rate, 6)},
            "detection": round(self.detection, 4), "power_met": self.power_met, "can_fail": self.can_fail,
            "false_alarm": round(self.false_alarm, 4), "false_alarm_expected": round(self.false_alarm_expected, 4),
        }


def family_confidence(bounds: int, family_alarm: float = FAMILY_ALARM) -> float:
    """The per-bound confidence that holds the chance of any of ``bounds`` independent bounds
    failing for unchanged agents to ``family_alarm`` (Sidak)."""
    if bounds < 1:
        raise ValueError(f"bounds: expected at least 1, got {bounds}")
    return (1.0 - family_alarm) ** (1.0 / bounds)


def derive_bound(agent: str, kind: str, successes: int, episodes: int, max_episodes: int, *,
                 confidence: float = CONFIDENCE, drop: float = DROP, power: float = POWER,
                 check_confidence: float | None = None) -> Bound:
    """The bound of ``agent`` from ``successes`` of ``episodes`` calibration episodes (see the
    module docstring): the smallest regression count ``n <= max_episodes`` whose bound can fail
    and catches a move of ``drop`` with probability ``power``; where none does, the smallest ``n``
    with the highest detection probability within the budget (1 when no bound can fail at all:
    the episode then only shows that the agent runs without crashing)."""
    if kind not in ("lower", "upper"):
        raise ValueError(f"kind: expected 'lower' or 'upper', got {kind!r}")
    _check_counts(successes, episodes)
    _check_counts(0, max_episodes)
    rate = successes / episodes
    count_at = lower_count if kind == "lower" else upper_count
    chosen, best = None, (-1.0, 0)
    for n in range(1, max_episodes + 1):
        c = count_at(rate, n, confidence)
        can_fail = c >= 1 if kind == "lower" else c < n
        det = detection_probability(kind, c, n, rate, drop) if can_fail else 0.0
        if det >= power:
            chosen = n
            break
        best = max(best, (det, -n))
    n = chosen or -best[1]
    c = count_at(rate, n, confidence if check_confidence is None else check_confidence)
    det = detection_probability(kind, c, n, rate, drop)
    return Bound(
        agent=agent, bound=kind, value=c / n, count=c, episodes=n, calibration_successes=successes,
        calibration_episodes=episodes, detection=det, power_met=det >= power,
        can_fail=c >= 1 if kind == "lower" else c < n, false_alarm=false_alarm_probability(kind, c, n, rate),
        false_alarm_expected=expected_false_alarm(kind, c, n, successes, episodes),
    )


# ------------------------------------------------------------------------------ suites and records
def regression_suites() -> list[Suite]:
    """The suites with calibrated bounds (those naming a ``calibration_file``), in registry order."""
    return [s for s in SUITES.values() if s.calibration_file is not None]


def _regression_suite(name: str) -> Suite:
    by_name = {s.name: s for s in regression_suites()}
    if name not in by_name:
        raise unknown_name_error("regression suite", name, by_name)
    return by_name[name]


def calibration_suite(suite: Suite) -> Suite:
    """``suite`` over its calibration episodes (all of them), named ``<suite>-calibration``."""
    if suite.calibration_file is None:
        raise HarnessError(f"suite {suite.name!r} has no calibration episodes (not a regression suite)")
    refuse_sealed_episodes(suite.calibration_file, "cfharness develop bounds")
    return suite_over(suite, f"{suite.name}-calibration", suite.calibration_file)


def records_file(suite: Suite, folder: Path = RECORDS_DIR) -> Path:
    """Where the calibration records of ``suite`` are committed."""
    return Path(folder) / f"{suite.name}.jsonl"


def _relative(path: Path) -> str:
    return Path(path).resolve().relative_to(SCENES_ROOT.resolve()).as_posix()


def _settings(suite: Suite) -> dict:
    """What a calibration must share with the regression run (stored in the bounds file)."""
    return {"episodes_file": _relative(suite.episodes_file), "calibration_file": _relative(suite.calibration_file),
            "env_kwargs": dict(suite.env_kwargs), "encoder": suite_encoder(suite, None), "seed": 0,
            "agents": list(suite.agents), "max_episodes": _max_episodes(suite)}


def _max_episodes(suite: Suite) -> int:
    available = len(suite_episodes(suite))
    return min(MAX_EPISODES.get(suite.name, available), available)


def load_calibration(suite: Suite, folder: Path = RECORDS_DIR) -> dict[str, list[bool]]:
    """Agent -> success per calibration episode (failure policy of :mod:`harness.report.stats`)
    from the committed records of ``suite``.

    Raises:
        HarnessError: records missing, or not covering every agent x calibration episode at seed
            0 with the suite's perception, or holding other episodes.
    """
    path = records_file(suite, folder)
    if not path.is_file():
        raise HarnessError(f"{path}: no calibration records for suite {suite.name!r}; run "
                           f"cfharness develop bounds --calibrate --suite {suite.name}")
    records = latest_records(load_results(path, strict=True))
    expected_ids = [e.episode_id for e in load_episodes(suite.calibration_file).episodes]
    name = calibration_suite(suite).name
    encoder = suite_encoder(suite, None)
    out: dict[str, list[bool]] = {}
    for agent in suite.agents:
        mine = {r["episode_id"]: r for r in records if r["agent"] == agent}
        missing = [e for e in expected_ids if e not in mine]
        extra = sorted(set(mine) - set(expected_ids))
        if missing or extra:
            raise HarnessError(f"{path}: agent {agent!r} has {len(mine)} records; missing calibration episodes "
                               f"{missing[:3]}{'...' if len(missing) > 3 else ''}, unexpected {extra[:3]}")
        for r in mine.values():
            want_encoder = encoder if "encoder" in (r.get("agent_kwargs") or {}) else "none"
            wrong = [(f, r.get(f), want) for f, want in (("suite", name), ("seed", 0), ("encoder", want_encoder))
                     if r.get(f) != want]
            if wrong:
                raise HarnessError(f"{path}: record of {agent!r} on {r['episode_id']}: " + "; ".join(
                    f"{f} {got!r}, expected {want!r}" for f, got, want in wrong))
        out[agent] = [bool(metric_value(mine[e], "success")) for e in expected_ids]
    others = sorted({r["agent"] for r in records} - set(suite.agents))
    if others:
        raise HarnessError(f"{path}: records of agents the suite does not run: {others}")
    return out


def derive_suite(suite: Suite, folder: Path = RECORDS_DIR, *, check_confidence: float | None = None) -> dict:
    """The bounds-file entry of one regression suite, recomputed from its committed records;
    ``check_confidence``: the level the counts are set at (default :data:`CONFIDENCE`)."""
    cal = load_calibration(suite, folder)
    max_n = _max_episodes(suite)
    agents = {}
    for agent, outcomes in cal.items():
        kind = "upper" if agent in UPPER_BOUND_AGENTS else "lower"
        agents[agent] = derive_bound(agent, kind, sum(outcomes), len(outcomes), max_n,
                                     check_confidence=check_confidence).as_json()
    return {"records": records_file(suite, folder).name, "settings": _settings(suite), "agents": agents}


def derive_bounds(folder: Path = RECORDS_DIR) -> dict:
    """The whole bounds file, recomputed from the committed calibration records.

    ``false_alarm_any_expected`` is the probability that at least one bound of all the suites
    fails for unchanged agents, ``1 - prod(1 - false_alarm_expected)`` (bounds independent): each
    bound's own false-alarm rate is small, but a gate of many bounds fails somewhere more often.
    """
    bounds = sum(len(load_calibration(s, folder)) for s in regression_suites())
    level = family_confidence(bounds)
    suites = {s.name: derive_suite(s, folder, check_confidence=level) for s in regression_suites()}
    quiet = 1.0
    for entry in suites.values():
        for b in entry["agents"].values():
            quiet *= 1.0 - b["false_alarm_expected"]
    return {
        "format": BOUNDS_FORMAT, "version": BOUNDS_VERSION,
        "method": {
            "confidence": CONFIDENCE, "drop": DROP, "power": POWER, "upper_bound_agents": sorted(UPPER_BOUND_AGENTS),
            "family_alarm": FAMILY_ALARM, "bounds": bounds, "check_confidence": round(level, 6),
            "counts": "episode counts chosen for per-bound power at `confidence`; bound counts set at `check_confidence` "
                      "so that the whole gate fails for unchanged agents with probability at most `family_alarm`",
            "lower": "largest c with P(Bin(n, p) < c) <= 1 - confidence, p = calibrated rate: fails iff the run's "
                     "one-sided Clopper-Pearson upper bound is below p",
            "upper": "smallest c with P(Bin(n, p) > c) <= 1 - confidence",
            "episodes": "smallest n <= max_episodes whose bound can fail and catches a move of `drop` with "
                        "probability >= power (exact binomial)",
        },
        "false_alarm_any_expected": round(1.0 - quiet, 4),
        "suites": suites,
    }


def _bounds_text(data: dict) -> str:
    return json.dumps(data, indent=1, sort_keys=False) + "\n"


def _strip(record: dict) -> dict:
    extras = {k: v for k, v in (record.get("extras") or {}).items() if k not in _DROPPED_EXTRAS}
    return {**record, "extras": extras}


def _claim_work_dir(work: Path, suites: list[Suite]) -> None:
    """Record the suites' settings in ``work/calibration.json``; refuse to resume a calibration
    whose settings differ (its records, keyed without the environment size, would be reused)."""
    path = work / "calibration.json"
    stored = read_json_file(path, "calibration settings file", HarnessError) if path.exists() else {}
    changed = [s.name for s in suites if s.name in stored and stored[s.name] != _settings(s)]
    if changed:
        raise HarnessError(f"{work}: the calibration there ran {', '.join(changed)} with other settings "
                           f"({path}); remove {work} (or those suites' records) to calibrate afresh")
    atomic_write_text(path, json.dumps({**stored, **{s.name: _settings(s) for s in suites}}, indent=1))


def calibrate(suites: list[Suite] | None = None, *, work_dir: str | Path = "runs/bounds-calibration",
              backend: str = "process", workers: int | None = None, folder: Path = RECORDS_DIR,
              bounds_file: Path = BOUNDS_FILE, progress: bool = True) -> dict:
    """Run the calibration episodes of ``suites`` (default: every regression suite) for every
    agent into ``work_dir/results.jsonl`` (an interrupted calibration resumes there), then write
    each suite's records to ``folder`` and the bounds recomputed from all committed records to
    ``bounds_file``, every file atomically. Returns the bounds data."""
    suites = list(suites or regression_suites())
    work = Path(work_dir)
    results = work / "results.jsonl"
    _claim_work_dir(work, suites)
    jobs = []
    for suite in suites:
        cal = calibration_suite(suite)
        config = RunConfig(suites=(suite.name,), backend=backend, workers=workers)
        jobs += episode_jobs(cal, config, uuid.uuid4().hex[:12])
    records = latest_records(run_missing_jobs(jobs, results, backend=backend, workers=workers, progress=progress))
    for suite in suites:
        name = calibration_suite(suite).name
        order = {a: i for i, a in enumerate(suite.agents)}
        mine = sorted((r for r in records if r["suite"] == name and r["agent"] in order),
                      key=lambda r: (order[r["agent"]], r["episode_id"]))
        text = "".join(json.dumps(_strip(r), allow_nan=False, separators=(",", ":")) + "\n" for r in mine)
        atomic_write_text(records_file(suite, folder), text)
    data = derive_bounds(folder)
    atomic_write_text(bounds_file, _bounds_text(data))
    return data


def replay_sample(suite: Suite, per_agent: int = 2, folder: Path = RECORDS_DIR, *, agents: tuple[str, ...] | None = None) -> list[str]:
    """Run again ``per_agent`` committed calibration episodes of each agent of ``suite`` (the first
    and, spread by a hash of the episode ids, others) in this process and compare their outcome
    with the committed records: ``status`` and every metric must come back exactly. Returns the
    differences (empty: the records are still what the code does), naming agent, episode, field,
    committed and new value. Committed records that the code no longer reproduces make every
    bound derived from them stale."""
    from harness.runner.tasks import run_episode

    cal = calibration_suite(suite)
    committed = [json.loads(line) for line in records_file(suite, folder).read_text().splitlines() if line.strip()]
    jobs = {(j.agent, j.episode.episode_id): j for j in episode_jobs(cal, RunConfig(suites=(suite.name,), backend="serial"), "replay")}
    problems = []
    for agent in agents or suite.agents:
        mine = sorted((r for r in committed if r["agent"] == agent), key=lambda r: r["episode_id"])
        picked = mine[:1] + sorted(mine[1:], key=lambda r: hashlib.sha256(r["episode_id"].encode()).hexdigest())[: per_agent - 1]
        for rec in picked:
            got = run_episode(jobs[(agent, rec["episode_id"])])
            where = f"{suite.name} {agent} {rec['episode_id']}"
            if got["status"] != rec["status"]:
                problems.append(f"{where}: status {rec['status']!r} committed, {got['status']!r} now ({(got.get('error') or '')[:120]})")
            for key in sorted(set(rec["metrics"]) | set(got["metrics"])):
                if rec["metrics"].get(key) != got["metrics"].get(key):
                    problems.append(f"{where}: metrics.{key} {rec['metrics'].get(key)!r} committed, {got['metrics'].get(key)!r} now")
    return problems


def _diff(want, got, path: str = "") -> list[str]:
    if isinstance(want, dict) and isinstance(got, dict):
        out = []
        for k in sorted(set(want) | set(got)):
            if k not in got:
                out.append(f"{path}/{k}: recomputed, missing from the committed file")
            elif k not in want:
                out.append(f"{path}/{k}: in the committed file, not recomputed")
            else:
                out += _diff(want[k], got[k], f"{path}/{k}")
        return out
    return [] if want == got else [f"{path}: recomputed {want!r}, committed {got!r}"]


def check(folder: Path = RECORDS_DIR, bounds_file: Path = BOUNDS_FILE) -> list[str]:
    """Differences between the bounds recomputed from the committed records and ``bounds_file``
    (empty: they agree)."""
    try:
        want = derive_bounds(folder)
    except (HarnessError, OSError, ValueError) as exc:
        return [str(exc)]
    if not Path(bounds_file).is_file():
        return [f"{bounds_file}: missing; run cfharness develop bounds --calibrate"]
    try:
        got = read_json_file(bounds_file, "bounds file", HarnessError)
    except ValueError as exc:
        return [f"{bounds_file}: not JSON ({exc})"]
    return _diff(want, got)


def _table(data: dict) -> str:
    lines = [f"{'suite':<30} {'agent':<16} {'bound':<8} {'value':>6} {'k/n':>9} {'calib':>9} {'rate':>5} "
             f"{'detect':>6} {'FA':>5} {'FA exp':>6}"]
    for suite, entry in data["suites"].items():
        for agent, b in entry["agents"].items():
            cal = b["calibration"]
            lines.append(
                f"{suite:<30} {agent:<16} {b['bound']:<8} {b['value']:>6.3f} {b['count']:>4}/{b['episodes']:<4} "
                f"{cal['successes']:>4}/{cal['episodes']:<4} {cal['rate']:>5.2f} {b['detection']:>6.2f} "
                f"{b['false_alarm']:>5.3f} {b['false_alarm_expected']:>6.3f}"
                + ("" if b["power_met"] else "  (power target not met)") + ("" if b["can_fail"] else "  (cannot fail)"))
    return "\n".join(lines)


def markdown_table(data: dict) -> str:
    """The bounds of ``data`` (a bounds file's content) as the Markdown table of
    ``docs/regression-gate.md``, one row per bound (the test suite checks the page holds exactly
    this table, recomputed from the committed records)."""
    lines = ["| suite | agent | bound | calibration | pinned episodes | detects a 15-point drop (rise) | false alarm (at p / expected) |",
             "|---|---|---|---|---|---|---|"]
    for suite, entry in data["suites"].items():
        for agent, b in entry["agents"].items():
            cal = b["calibration"]
            detect = f"{b['detection']:.2f}" + ("" if b["can_fail"] else " (cannot fail)")
            lines.append(f"| `{suite}` | `{agent}` | {b['bound']} {b['value']:.3f} ({b['count']} of {b['episodes']}) | "
                         f"{cal['successes']}/{cal['episodes']} ({cal['rate']:.2f}) | {b['episodes']} | {detect} | "
                         f"{b['false_alarm']:.3f} / {b['false_alarm_expected']:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.runner.bounds", description=__doc__.splitlines()[0])
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--calibrate", action="store_true", help="run the calibration episodes, write records and bounds")
    what.add_argument("--check", action="store_true", help="recompute the bounds from the committed records and compare")
    what.add_argument("--derive", action="store_true", help="recompute the bounds from the committed records and write them")
    ap.add_argument("--suite", action="append", help="regression suite to calibrate (repeatable; default: all)")
    ap.add_argument("--work", default="runs/bounds-calibration", help="folder of the calibration run (resumable)")
    ap.add_argument("--backend", default="process", help="where episodes run (process, serial, ray)")
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: CPU count)")
    args = ap.parse_args(argv)
    if args.calibrate:
        try:
            suites = [_regression_suite(n) for n in args.suite] if args.suite else None
            data = calibrate(suites, work_dir=args.work, backend=args.backend, workers=args.workers)
        except (HarnessError, ValueError, OSError) as exc:
            print(f"bounds --calibrate: {exc}", file=sys.stderr)
            return 2
        print(_table(data))
        print(f"wrote {BOUNDS_FILE}")
        return 0
    if args.derive:
        data = derive_bounds()
        atomic_write_text(BOUNDS_FILE, _bounds_text(data))
        print(_table(data))
        print(f"wrote {BOUNDS_FILE}")
        return 0
    problems = check()
    for line in problems:
        print(f"bounds --check: {line}", file=sys.stderr)
    if not problems:
        print(_table(json.loads(BOUNDS_FILE.read_text())))
        print("bounds match the committed calibration records")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
