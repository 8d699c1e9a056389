"""The report's first screen: per suite the best agent, its matched twin or declared baseline, the
paired difference and a verdict, from records with hand-counted outcomes; and the metric labels."""

import pytest

from harness.report.cards import GENERIC_QUESTION, MIN_PAIRS, answer_card, headline_cards, suite_answer, suite_answers
from harness.report.labels import column_order, metric_label, metric_title
from harness.runner.results import make_record
from harness.runner.suites import SUITES


def _rec(suite, agent, i, metrics, encoder="e", **extras):
    return make_record(run_id="r", suite=suite, task="t", agent=agent, encoder=encoder, episode_id=f"ep{i:02d}", seed=0,
                       status="ok", metrics=metrics, extras=extras)


def _search(n=12, map_wins=10, twin_wins=2, suite="search-v2"):
    """Map agent, its twin and a random walker; the map agent succeeds wherever the twin does."""
    recs = []
    for i in range(n):
        recs.append(_rec(suite, "map-navigator", i, {"success": i < map_wins}, uses_map=True))
        recs.append(_rec(suite, "twin-navigator", i, {"success": i < twin_wins}, uses_map=False, twin_of="map-navigator"))
        recs.append(_rec(suite, "random-walker", i, {"success": False}, encoder="none", uses_map=False))
    return recs


def test_map_agent_against_its_twin():
    a = suite_answer(_search(), "search-v2")
    assert a.question == SUITES["search-v2"].question and a.metric == "success"
    assert a.best == ("map-navigator", "e") and a.best_stat.mean == pytest.approx(10 / 12)
    assert (a.compared, a.baseline) == (("map-navigator", "e"), ("twin-navigator", "e"))
    res = a.comparison
    assert res.n_pairs == 12 and res.mean_diff == pytest.approx(8 / 12) and (res.a_only, res.b_only) == (8, 0)
    assert res.p_value == pytest.approx(2 / 2**8)  # exact McNemar: 2 P(X <= 0), X ~ Bin(8, 1/2)
    assert res.ci_low > 0 and (a.verdict, a.tone) == ("map helps", "better")
    card = answer_card(a)
    assert card.best == "map-navigator (e)" and card.figure.startswith("success 0.83 [")
    assert card.against == "twin-navigator (matched map-free twin) 0.17"
    assert card.difference.startswith("+0.67 [") and card.test == "p 0.0078 (exact McNemar), 12 pairs"
    assert card.href == "#section-search-v2"


def test_verdicts_follow_the_interval():
    same = suite_answer(_search(map_wins=6, twin_wins=6), "search-v2")  # identical outcomes: interval [0, 0]
    assert (same.verdict, same.tone) == ("no detectable difference", "same")
    recs = [_rec("s", "map-navigator", i, {"success": i < 2}) for i in range(12)]
    recs += [_rec("s", "twin-navigator", i, {"success": i < 11}, twin_of="map-navigator") for i in range(12)]
    worse = suite_answer(recs, "s")
    # the twin is best; the card still compares the map agent with it, and says which way
    assert worse.best == ("twin-navigator", "e") and worse.compared == ("map-navigator", "e")
    assert (worse.verdict, worse.tone) == ("map hurts", "worse") and worse.comparison.ci_high < 0
    assert answer_card(worse).against == "map-navigator 0.17 against twin-navigator (matched map-free twin) 0.92"
    few = suite_answer(_search(n=MIN_PAIRS - 1, map_wins=9, twin_wins=0), "search-v2")
    assert few.comparison.ci_low > 0 and few.verdict == "too few to tell" and f"{MIN_PAIRS - 1} pairs" in few.note


def test_privileged_results_are_marked_and_never_the_winner_over_robots():
    recs = _search()
    recs += [_rec("search-v2", "oracle-searcher", i, {"success": True}, encoder="oracle", privileged=True) for i in range(12)]
    a = suite_answer(recs, "search-v2")
    assert a.best == ("map-navigator", "e")
    assert "oracle-searcher (oracle) (privileged) scores 1.00, not ranked" in a.note
    only = [_rec("s", "oracle-searcher", i, {"success": i < 6}, encoder="oracle", privileged=True) for i in range(12)]
    card = answer_card(suite_answer(only, "s"))
    assert card.best == "oracle-searcher (oracle) (privileged)" and card.against == ""


def test_declared_baseline_when_no_twin_ran():
    """spatial-v2 declares frame-2.5d: the best other agent is compared with it (a mean: Wilcoxon)."""
    recs = []
    for i in range(12):
        recs.append(_rec("spatial-v2", "map-3d", i, {"accuracy": 0.5 + 0.01 * i}))
        recs.append(_rec("spatial-v2", "frame-2.5d", i, {"accuracy": 0.7 + 0.01 * i}))
    a = suite_answer(recs, "spatial-v2")
    assert a.metric == "accuracy" and a.best == ("frame-2.5d", "e")  # the baseline itself is best here
    assert (a.compared, a.baseline) == (("map-3d", "e"), ("frame-2.5d", "e")) and a.role == "suite baseline"
    assert a.comparison.mean_diff == pytest.approx(-0.2) and not a.comparison.binary
    assert a.verdict == "map hurts"
    assert "Wilcoxon" in answer_card(a).test


def test_unknown_suite_gets_a_generic_card_ranked_by_its_first_metric():
    recs = [_rec("mine", agent, i, {"score": v + 0.01 * i, "other": 1.0}) for i in range(4) for agent, v in (("a", 0.2), ("b", 0.6))]
    a = suite_answer(recs, "mine")
    assert a.question == GENERIC_QUESTION and a.metric == "score" and a.best == ("b", "e")
    assert a.compared is None and a.verdict == ""
    card = answer_card(a)
    assert card.figure.startswith("other score 0.6") and card.difference == ""
    assert suite_answer([_rec("empty", "a", 0, {})], "empty") is None


def test_cards_put_twin_suites_first_and_are_recomputed_from_the_records():
    recs = _search(suite="search-v2") + [_rec("query-v2", "conceptfusion", i, {"text_miou": 0.4}) for i in range(3)]
    recs += [_rec("ablation-v2", v, i, {"macc": m}) for i in range(12) for v, m in (("full", 0.5), ("global", 0.1))]
    assert [a.suite for a in suite_answers(recs)] == ["search-v2", "ablation-v2", "query-v2"]
    cards = headline_cards(recs).cards
    assert cards[1].verdict == "beats global only" and cards[1].figure.startswith("segmentation mAcc 0.50")
    flip = {"map-navigator": False, "twin-navigator": True}
    changed = [dict(r, metrics={"success": flip[r["agent"]]}) if r["agent"] in flip else r for r in recs]
    assert headline_cards(changed).cards[0].verdict == "map hurts"


@pytest.mark.parametrize("name, label", [
    ("name_miou", ("name", "mIoU")), ("held_out_category_acc25", ("held-out category", "acc@0.25")),
    ("text_miou_thresh", ("text", "mIoU at floor")), ("acc_howFar", ("howFar", "accuracy")), ("n_howFar", ("howFar", "questions")),
    ("spl", ("", "SPL")), ("reached_2", ("chain", "first 2")), ("macc", ("segmentation", "mAcc")), ("odd_thing", ("other", "odd thing")),
])
def test_metric_labels(name, label):
    assert metric_label(name) == label


def test_column_order_puts_the_headline_group_after_the_ungrouped_columns():
    names = ["map_points", "synonym_miou", "name_found_rate", "name_miou", "success", "absent_fp_rate"]
    assert column_order(names, first_group="synonym") == ["success", "synonym_miou", "name_miou", "name_found_rate",
                                                          "absent_fp_rate", "map_points"]
    assert metric_title("name_miou") == "name mIoU" and metric_title("success") == "success"
    with pytest.raises(TypeError, match="expected a non-empty string, got ''"):
        metric_label("")


def test_a_tie_goes_to_the_map_agent():
    """Every agent succeeding everywhere: the map agent is named best, not the alphabetically first
    frame agent (the question is about the map)."""
    recs = []
    for i in range(10):
        recs.append(_rec("rearrange-v2", "frame-pusher", i, {"success": True}, uses_map=False))
        recs.append(_rec("rearrange-v2", "map-pusher", i, {"success": True}, uses_map=True))
        recs.append(_rec("rearrange-v2", "twin-pusher", i, {"success": True}, uses_map=False, twin_of="map-pusher"))
    a = suite_answer(recs, "rearrange-v2")
    assert a.best == ("map-pusher", "e") and (a.compared, a.baseline) == (("map-pusher", "e"), ("twin-pusher", "e"))
    assert a.verdict == "no detectable difference"


def test_an_oracle_is_not_the_best_when_every_agent_is_privileged():
    """With privileged perception every agent is privileged; the oracle (no perception, it reads
    the goal) is still the upper bound, so the card compares the planner agents."""
    recs = []
    for i in range(12):
        recs.append(_rec("instruct-v2", "map-planner", i, {"success": i < 9}, encoder="oracle-open", privileged=True))
        recs.append(_rec("instruct-v2", "generic-planner", i, {"success": i < 5}, encoder="oracle-open", privileged=True))
        recs.append(_rec("instruct-v2", "oracle-searcher", i, {"success": True}, encoder="none", privileged=True))
    a = suite_answer(recs, "instruct-v2")
    assert a.best == ("map-planner", "oracle-open") and a.compared == a.best
    assert a.baseline == ("generic-planner", "oracle-open") and a.verdict == "map context helps"
