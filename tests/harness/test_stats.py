"""Statistics: Wilson and bootstrap intervals, summaries, paired comparisons, per-category rates."""

import math

import numpy as np
import pytest

from harness.runner.results import make_record
from harness.report.stats import (
    bootstrap_ci, mcnemar_exact, metric_value, paired_comparison, per_category, summarize, wilson_interval,
)


def _rec(agent, episode_id, success, spl=None, *, seed=0, status="ok", suite="search", encoder="test",
         category=None, wall_s=2.0, agent_kwargs=None):
    metrics = {"success": success}
    if spl is not None:
        metrics["spl"] = spl
    return make_record(run_id="r", suite=suite, task="object_search", agent=agent, agent_kwargs=agent_kwargs or {},
                       encoder=encoder, episode_id=episode_id, seed=seed, status=status, metrics=metrics,
                       timings={"wall_s": wall_s}, category=category)


def test_wilson_known_values():
    low, high = wilson_interval(8, 10)
    # by hand: z = 1.95996, centre = (0.8 + z^2/20) / (1 + z^2/10), half = z sqrt(0.016 + z^2/400) / (1 + z^2/10)
    assert low == pytest.approx(0.4902, abs=1e-3) and high == pytest.approx(0.9433, abs=1e-3)
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(10, 10)[1] == 1.0
    assert wilson_interval(0, 10)[1] == pytest.approx(0.2775, abs=1e-3)
    lo99, hi99 = wilson_interval(8, 10, confidence=0.99)
    assert lo99 < low and hi99 > high
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    with pytest.raises(ValueError, match="0 <= successes <= n"):
        wilson_interval(11, 10)
    with pytest.raises(ValueError, match=r"confidence: expected a value in \(0, 1\)"):
        wilson_interval(1, 2, confidence=95)


def test_bootstrap_contains_mean_and_narrows():
    rng = np.random.default_rng(1)
    small, large = rng.normal(3.0, 1.0, 20), rng.normal(3.0, 1.0, 2000)
    lo_s, hi_s = bootstrap_ci(small)
    lo_l, hi_l = bootstrap_ci(large)
    assert lo_s < small.mean() < hi_s and lo_l < large.mean() < hi_l
    assert (hi_l - lo_l) < (hi_s - lo_s) / 4
    assert bootstrap_ci(small, seed=3) == bootstrap_ci(small, seed=3)
    lo_m, hi_m = bootstrap_ci(small, statistic=lambda v: float(np.median(v)))
    assert lo_m <= np.median(small) <= hi_m
    assert all(math.isnan(v) for v in bootstrap_ci([]))
    with pytest.raises(ValueError, match="1-D"):
        bootstrap_ci(np.zeros((2, 2)))


def test_summarize_groups_and_failure_policy():
    recs = [_rec("nav", f"e{i}", i < 6, 0.5 if i < 6 else 0.0, agent_kwargs={"k": 1}) for i in range(8)]
    recs.append(_rec("nav", "e8", True, 0.9, status="failed", agent_kwargs={"k": 1}))  # crash: unsuccessful, spl 0
    recs.append(_rec("nav", "e9", None, None, status="timeout", agent_kwargs={"k": 1}))
    recs += [_rec("walk", f"e{i}", i < 2, wall_s=1.0) for i in range(10)]
    rows = summarize(recs)
    assert [(r.agent, r.n) for r in rows] == [("nav[k=1]", 10), ("walk", 10)]
    nav = rows[0]
    assert (nav.n_failed, nav.n_timeout) == (1, 1)
    assert nav.metrics["success"].mean == pytest.approx(0.6) and nav.metrics["success"].rate
    assert (nav.metrics["success"].low, nav.metrics["success"].high) == pytest.approx(wilson_interval(6, 10))
    assert nav.metrics["spl"].mean == pytest.approx(0.3) and not nav.metrics["spl"].rate
    assert nav.metrics["spl"].low <= 0.3 <= nav.metrics["spl"].high
    assert "spl" not in rows[1].metrics and rows[1].wall_s == pytest.approx(1.0)
    d = nav.as_dict()
    assert d["success"] == pytest.approx(0.6) and d["success_n"] == 10 and d["agent"] == "nav[k=1]"
    assert metric_value(recs[8], "success") is False


def test_summarize_counts_a_retried_episode_once():
    recs = [_rec("nav", "e0", False, status="failed"), _rec("nav", "e0", True)]
    (row,) = summarize(recs)
    assert row.n == 1 and row.metrics["success"].mean == 1.0 and row.n_failed == 0


def _two_agents(rng, p_a, p_b, n=60, seeds=(0,)):
    recs = []
    for seed in seeds:
        for i in range(n):
            recs.append(_rec("map-nav", f"e{i}", bool(rng.random() < p_a), seed=seed))
            recs.append(_rec("walker", f"e{i}", bool(rng.random() < p_b), seed=seed, encoder="none"))
    return recs


def test_paired_comparison_detects_a_better_agent():
    recs = _two_agents(np.random.default_rng(0), 0.9, 0.2)
    res = paired_comparison(recs, "map-nav", "walker", encoder="test", encoder_b="none")
    assert res.n_pairs == 60 and res.binary
    assert res.mean_diff > 0 and res.ci_low > 0
    assert res.a_only > res.b_only and res.p_value < 1e-4
    assert res.mean_diff == pytest.approx(res.mean_a - res.mean_b)
    assert res.p_value == pytest.approx(mcnemar_exact(res.a_only, res.b_only))
    flipped = paired_comparison(recs, "walker", "map-nav", encoder="none", encoder_b="test")
    assert flipped.mean_diff == pytest.approx(-res.mean_diff) and flipped.p_value == pytest.approx(res.p_value)


def test_paired_comparison_identical_agents_p_is_one():
    recs = []
    for i in range(20):
        recs.append(_rec("a", f"e{i}", i % 3 == 0, spl=0.1 * (i % 4)))
        recs.append(_rec("b", f"e{i}", i % 3 == 0, spl=0.1 * (i % 4)))
    res = paired_comparison(recs, "a", "b")
    assert res.p_value == 1.0 and res.mean_diff == 0.0 and (res.a_only, res.b_only) == (0, 0)
    spl = paired_comparison(recs, "a", "b", metric="spl")
    assert not spl.binary and spl.p_value == 1.0 and spl.ci_low == spl.ci_high == 0.0


def test_mcnemar_exact_by_hand():
    # 5 vs 0 discordant: 2 * (1/2)^5 = 0.0625
    assert mcnemar_exact(5, 0) == pytest.approx(0.0625)
    assert mcnemar_exact(3, 3) == 1.0
    assert mcnemar_exact(0, 0) == 1.0


def test_paired_comparison_errors():
    recs = [_rec("a", "e0", True), _rec("b", "e1", False)]
    with pytest.raises(ValueError, match="no episodes pair up"):
        paired_comparison(recs, "a", "b")
    with pytest.raises(ValueError, match=r"no records of agent 'aa'.*did you mean 'a'\?"):
        paired_comparison(recs, "aa", "b")
    recs = [_rec("a", "e0", True), _rec("a", "e0", True, encoder="other"), _rec("b", "e0", False)]
    with pytest.raises(ValueError, match="several encoders"):
        paired_comparison(recs, "a", "b")
    assert paired_comparison(recs, "a", "b", encoder="other", encoder_b="test").n_pairs == 1
    with pytest.raises(ValueError, match="no records of agent 'b'.*encoder='other'"):
        paired_comparison(recs, "a", "b", encoder="other")


def test_per_category():
    recs = [_rec("a", f"e{i}", i % 2 == 0, category="mug" if i < 4 else "bowl") for i in range(6)]
    recs.append(_rec("a", "e6", True))  # no category: left out
    recs.append(_rec("a", "e7", True, category="bowl", status="failed"))
    out = per_category(recs)
    assert out == {("search", "a", "test"): {"bowl": (pytest.approx(1 / 3), 3), "mug": (0.5, 4)}}
