"""Readable names for the metrics the records carry: one table, used by every report table and card.

A metric name becomes ``(group, column)``: ``name_miou`` -> ("name", "mIoU"), ``acc_howFar`` ->
("howFar", "accuracy"), ``spl`` -> ("", "SPL"). Columns of one group sit together under the group's
name in the HTML report (which can hide a group); the Markdown report writes ``group: column``.
``success`` and ``SPL`` are in no group: they are the outcome of an episode and always shown.

Names are looked up in :data:`EXACT` first, then by suffix (:data:`SUFFIXES`, the query suites'
``<kind>_<measure>``), then by prefix (:data:`PREFIXES`, the spatial suite's ``acc_<comparator>``
and the chain suite's ``reached_<k>``); any other name is its own column in the group ``other``.
"""

from __future__ import annotations

__all__ = ["EXACT", "SUFFIXES", "PREFIXES", "GROUP_ORDER", "metric_label", "metric_title", "column_order"]

EXACT: dict[str, tuple[str, str]] = {
    "success": ("", "success"),
    "spl": ("", "SPL"),
    "steps": ("path", "steps"),
    "path_length": ("path", "length (m)"),
    "shortest_path_length": ("path", "shortest (m)"),
    "distance_to_goal": ("path", "to goal (m)"),
    "collisions": ("path", "collisions"),
    "chain_length": ("chain", "goals"),
    "goals_reached": ("chain", "reached"),
    "accuracy": ("overall", "accuracy"),
    "accuracy_fresh": ("overall", "fresh phrasings"),
    "accuracy_seen": ("overall", "common phrasings"),
    "n_questions": ("overall", "questions"),
    "accuracy_parsed": ("parser", "accuracy when parsed"),
    "parse_rate": ("parser", "parsed"),
    "parse_fail_rate": ("parser", "refused"),
    "notfound_rate": ("parser", "object not found"),
    "chance_always_yes": ("chance", "always yes"),
    "chance_random": ("chance", "coin toss"),
    "macc": ("segmentation", "mAcc"),
    "fmiou": ("segmentation", "f-mIoU"),
    "pixel_acc": ("segmentation", "pixel accuracy"),
    "coverage": ("segmentation", "coverage"),
    "absent_fp_rate": ("absent", "false positives"),
    "n_absent": ("absent", "queries"),
    "n_queries": ("counts", "queries"),
    "n_unseen": ("counts", "unseen"),
    "n_objects": ("counts", "objects"),
    "n_skipped": ("counts", "skipped"),
    "n_classes": ("map", "classes"),
    "map_points": ("map", "points"),
    "miou": ("", "mIoU"),
}
"""Whole metric names -> (group, column)."""

SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_miou", "mIoU"),
    ("_acc15", "acc@0.15"),
    ("_acc25", "acc@0.25"),
    ("_acc50", "acc@0.50"),
    ("_found_rate", "found"),
    ("_miou_thresh", "mIoU at floor"),
)
"""``<group>_<suffix>`` -> column (the group is the part before the suffix); in column order."""

PREFIXES: tuple[tuple[str, str], ...] = (
    ("acc_", "accuracy"),
    ("n_", "questions"),
)
"""``<prefix><group>`` -> column; in column order."""

GROUP_ORDER = ("", "overall", "text", "image", "click", "name", "synonym", "parent", "colour", "material", "function",
               "absent", "seen", "validation", "held-out instance", "held-out category", "segmentation", "chain", "path",
               "parser", "chance")
"""Groups in the order their columns appear; any other group follows in name order, then
``counts``, ``map`` and ``other`` last."""
_LAST = ("counts", "map", "other")


def _group_name(raw: str) -> str:
    return raw.replace("held_out_", "held-out ").replace("_", " ")


def metric_label(name: str) -> tuple[str, str]:
    """``(group, column)`` of a metric name (group ``""``: in no group).

    >>> metric_label("held_out_category_acc25")
    ('held-out category', 'acc@0.25')
    """
    if not isinstance(name, str) or not name:
        raise TypeError(f"metric name: expected a non-empty string, got {name!r}")
    if name in EXACT:
        return EXACT[name]
    for suffix, column in SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return _group_name(name[: -len(suffix)]), column
    if name.startswith("reached_") and name[len("reached_"):].isdigit():
        k = int(name[len("reached_"):])
        return "chain", f"first {k}" if k > 1 else "first goal"
    for prefix, column in PREFIXES:
        if name.startswith(prefix) and len(name) > len(prefix):
            return _group_name(name[len(prefix):]), column
    return "other", name.replace("_", " ")


def metric_title(name: str) -> str:
    """One line naming a metric: ``"name mIoU"``, ``"success"``."""
    group, column = metric_label(name)
    return f"{group} {column}" if group else column


def _column_rank(name: str, column: str) -> tuple:
    if name in EXACT:
        return (0, list(EXACT).index(name))
    for i, (suffix, _) in enumerate(SUFFIXES):
        if name.endswith(suffix):
            return (1, i)
    if name.startswith("reached_") and name[len("reached_"):].isdigit():
        return (2, int(name[len("reached_"):]))
    for i, (prefix, _) in enumerate(PREFIXES):
        if name.startswith(prefix):
            return (3, i)
    return (4, column)


def column_order(names, first_group: str | None = None) -> list[str]:
    """Metric names in table order: ungrouped first, then ``first_group`` (the headline's), then
    the groups of :data:`GROUP_ORDER`, the others by name, and ``counts``, ``map``, ``other``."""
    def key(name: str) -> tuple:
        group, column = metric_label(name)
        if group == "":
            g = (0, 0, "")
        elif group == first_group:
            g = (1, 0, "")
        elif group in GROUP_ORDER:
            g = (2, GROUP_ORDER.index(group), "")
        elif group in _LAST:
            g = (4, _LAST.index(group), "")
        else:
            g = (3, 0, group)
        return (*g, _column_rank(name, column))
    return sorted(set(names), key=key)
