"""The report's episode figures: top-down paths of a few episodes per agent, and query heatmaps.

Both take a writer ``w`` with ``w.figure(stem, png) -> file name`` and ``w.skip(what, why)``
(:class:`harness.report.markdown._Writer`) and return report blocks.

- Paths (records with ``extras.path_xy``): per (agent, encoder), up to :data:`PATH_EPISODES`
  episodes, successes and failures both (failures of different causes first), each panel with
  its outcome and cause, its goal text (``extras.goal``; the category when not recorded), start,
  end, the goal object and the success region (its footprint, from the scene file, grown by the
  success radius) over the floor plan of ``extras.scene``.
- Heatmaps (records with ``extras.heatmap_npz``, written by :mod:`harness.maps.query`): the
  query's relevancy from above, cropped to the table and its objects, titled with the query, the
  object's ground-truth box and the answer's region drawn, and the verdict (found or not, right
  or wrong by IoU). Files of the first format (``points``, ``values``, ``query`` only) are read
  too: the verdict then comes from the record's ``extras.queries``, the box from the shipped
  scene's file, the crop from the points above the floor; the figure says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.report import plots as report_plots
from harness.report.causes import failure_cause, goal_text, is_failure, success_radius
from harness.report.document import Figure, Heading, Paragraph
from harness.report.stats import group_key

__all__ = ["path_figures", "heatmap_figures", "PATH_EPISODES", "MAX_HEATMAPS", "HeatmapView", "read_heatmap"]

PATH_EPISODES = 4
"""Episodes drawn per (agent, encoder) of a suite: up to half successes, the rest failures."""
MAX_HEATMAPS = 4
"""Query heatmaps drawn per report (wrong and right answers alternating)."""

_FLOOR_Z = 0.05
"""Metres: points below this are the floor, left out of an old heatmap file's crop."""
_MARGIN = 0.06
"""Metres around the table and objects in a heatmap's crop."""
_RIGHT_IOU = 0.25
"""IoU a found answer must pass to be right, for files that predate ``right_iou``
(:data:`harness.maps.query.RIGHT_IOU`, not imported: that module loads the simulator)."""


def _scene(ref: str, cache: dict):
    """(scene, its occupancy grid or None) of a scene file under ``scenes/`` (or absolute), or the
    exception that stopped loading it."""
    if ref not in cache:
        from sim_envs.scenes.episodes import SCENES_ROOT
        from sim_envs.scenes.floorplan import occupancy_grid
        from sim_envs.scenes.format import load_scene

        path = Path(ref) if Path(ref).is_absolute() else SCENES_ROOT / ref
        try:
            scene = load_scene(path)
            cache[ref] = (scene, occupancy_grid(scene) if scene.rooms else None)
        except (OSError, ValueError) as exc:
            cache[ref] = exc
    return cache[ref]


def _goal_box(scene, record: dict, goal_xy) -> np.ndarray | None:
    """The xy footprint (2, 2) of the scene object of the record's category nearest ``goal_xy``
    (within 0.5 m), None when there is none."""
    if goal_xy is None or not record.get("category"):
        return None
    goal = np.asarray(goal_xy, dtype=np.float64)[:2]
    best, box = 0.5, None
    for o in scene.objects:
        if o.category != record["category"]:
            continue
        lo, hi = o.footprint()
        d = float(np.linalg.norm((lo + hi) / 2 - goal))
        if d <= best:
            best, box = d, np.stack([lo, hi])
    return box


def _choose(records: list[dict]) -> list[dict]:
    """Up to :data:`PATH_EPISODES`: failures of different causes first, up to half successes,
    filled from either; by episode id and seed within each kind."""
    ordered = sorted(records, key=lambda r: (str(r["episode_id"]), r["seed"]))
    wins = [r for r in ordered if not is_failure(r)]
    losses = [r for r in ordered if is_failure(r)]
    seen, first, rest = set(), [], []
    for r in losses:  # one of each cause first, so the panels show different ways of failing
        (first if failure_cause(r) not in seen else rest).append(r)
        seen.add(failure_cause(r))
    losses = first + rest
    n_wins = min(len(wins), PATH_EPISODES // 2, max(PATH_EPISODES - len(losses), PATH_EPISODES // 2))
    n_losses = min(len(losses), PATH_EPISODES - n_wins)
    n_wins = min(len(wins), PATH_EPISODES - n_losses)
    by_id = lambda r: (str(r["episode_id"]), r["seed"])  # noqa: E731
    return sorted(losses[:n_losses], key=by_id) + wins[:n_wins]


def _panel(r: dict, cache: dict, w) -> dict:
    ex = r["extras"]
    cause = failure_cause(r)
    d = (r.get("metrics") or {}).get("distance_to_goal")
    far = f", {d:.1f} m from the goal" if isinstance(d, (int, float)) and not isinstance(d, bool) else ""
    outcome = "success" if cause is None else f"{'miss' if r['status'] == 'ok' else r['status']} ({cause}{far})"
    radius, recorded = success_radius(r)
    goal = goal_text(r)
    panel = {"path_xy": ex["path_xy"], "start_xy": ex.get("start_xy"), "goal_xy": ex.get("goal_xy"),
             "label": f"{r['episode_id']} seed {r['seed']}: {outcome}", "ok": cause is None,
             "goal": f'goal: "{goal}"' if goal else f"goal: a {r.get('category') or '?'} (category; no goal text recorded)",
             "radius": radius, "radius_recorded": recorded}
    scene_ref = ex.get("scene")
    loaded = _scene(str(scene_ref), cache) if scene_ref else None
    if isinstance(loaded, Exception):
        w.skip(f"floor plan of {scene_ref} ({r['episode_id']})", str(loaded))
    elif loaded is not None:
        scene, grid = loaded
        if grid is not None:
            panel.update(blocked_hw=grid.blocked_hw, origin=grid.origin, cell=grid.cell)
        panel["goal_box"] = _goal_box(scene, r, ex.get("goal_xy"))
    else:
        w.skip(f"floor plan for {r['episode_id']} ({r['agent']})", "record names no extras.scene")
    return panel


def path_figures(records, suite: str, w) -> list:
    """One figure per (agent, encoder) of ``suite`` whose records carry ``extras.path_xy``."""
    blocks, cache = [], {}
    by_group: dict[tuple, list[dict]] = {}
    for r in records:
        if (r.get("extras") or {}).get("path_xy"):
            by_group.setdefault(group_key(r), []).append(r)
    for key in sorted(by_group):
        chosen = _choose(by_group[key])
        panels = [_panel(r, cache, w) for r in chosen]
        n_fail = sum(not p["ok"] for p in panels)
        try:
            png = report_plots.topdown_paths(panels, title=f"{key[1]} ({key[2]}), suite {suite}: "
                                             f"{n_fail} failed and {len(panels) - n_fail} successful episodes")
        except (ValueError, TypeError) as exc:
            w.skip(f"top-down paths of {key[1]} ({key[2]})", str(exc))
            continue
        name = w.figure(f"paths_{suite}_{key[1]}_{key[2]}", png)
        blocks.append(Figure(name, f"paths of {key[1]} ({key[2]})"))
    return blocks


class HeatmapView:
    """What a heatmap figure draws, read from a heatmap file and its record (see :func:`read_heatmap`)."""

    def __init__(self, points_n3, values_n, query: str, crop_xy, gt_box_xy, answer_box_xy,
                 found: bool | None, iou: float | None, right_iou: float, notes: list[str]):
        self.points_n3, self.values_n, self.query = points_n3, values_n, query
        self.crop_xy, self.gt_box_xy, self.answer_box_xy = crop_xy, gt_box_xy, answer_box_xy
        self.found, self.iou, self.right_iou, self.notes = found, iou, right_iou, notes

    def brightest_offset(self) -> float | None:
        """Metres (xy) from the ground-truth box to the point of highest relevancy (0: on the
        object); None without a box or a positive value."""
        if self.gt_box_xy is None or not len(self.values_n) or not np.nanmax(self.values_n) > 0:
            return None
        xy = self.points_n3[int(np.nanargmax(self.values_n)), :2]
        gap = np.maximum(0.0, np.maximum(self.gt_box_xy[0] - xy, xy - self.gt_box_xy[1]))
        return float(np.hypot(*gap))

    @property
    def right(self) -> bool | None:
        """Whether the answer is right (found, IoU above ``right_iou``); None when unknown."""
        if self.found is None:
            return None
        return bool(self.found and self.iou is not None and self.iou > self.right_iou)

    def verdict(self) -> str:
        """The verdict line: found or not, right or wrong, and why."""
        if self.found is None:
            return "verdict unknown: neither the file nor the record holds this query's score"
        off = self.brightest_offset()
        where = "" if off is None else ("; the brightest point is on the object" if off < 0.01 else
                                        f"; the brightest point is {off:.2f} m from the object")
        if not self.found:
            return "not found: wrong, the object is on the table" + where
        iou = "?" if self.iou is None else f"{self.iou:.2f}"
        if self.right:
            return f"found: right, IoU {iou} with the object (> {self.right_iou:g})" + where
        return f"found: wrong place, IoU {iou} with the object (needs > {self.right_iou:g})" + where


def _first_text_query(record: dict) -> dict | None:
    queries = (record.get("extras") or {}).get("queries")
    if isinstance(queries, list) and queries and isinstance(queries[0], dict):
        return queries[0]
    return None


def _scene_object_box(record: dict, query: dict | None, name: str):
    """The xy footprint of the queried object in the shipped scene named by the episode id, or
    (None, why not)."""
    try:
        from harness.maps.scan import load_shipped_scene

        scene = load_shipped_scene(str(record["episode_id"]))
    except (ValueError, OSError) as exc:
        return None, f"no ground-truth box: {exc}"
    oid = (query or {}).get("object")
    for o in scene.objects:
        if o.id == oid or (oid is None and o.name == name):
            lo, hi = o.footprint()
            return np.stack([lo, hi]), "ground-truth box: the object's footprint in the scene file"
    return None, f"no ground-truth box: scene {scene.id} has no object {oid or name!r}"


def _box_xy(box) -> np.ndarray:
    return np.asarray(box, dtype=np.float64).reshape(2, -1)[:, :2]


def read_heatmap(path: Path, record: dict) -> HeatmapView:
    """Read a heatmap file (either format, see the module docstring) with its record's fallbacks.

    Raises ``OSError``/``ValueError`` for an unreadable file and ``KeyError`` for one without
    ``points`` or ``values``.
    """
    with np.load(path) as npz:
        data = {k: npz[k] for k in npz.files}
    points = np.asarray(data["points"], dtype=np.float64).reshape(-1, 3)
    values = np.asarray(data["values"], dtype=np.float64).reshape(-1)
    query_rec = _first_text_query(record)
    name = str(data["query"]) if "query" in data else str((query_rec or {}).get("name")
                                                         or (record.get("extras") or {}).get("query") or "?")
    notes: list[str] = []
    right_iou = float(data["right_iou"]) if "right_iou" in data else _RIGHT_IOU
    if "found" in data:
        found, iou = bool(data["found"]), float(data["iou"])
    else:
        scored = (query_rec or {}).get("text") if (query_rec or {}).get("name") == name else None
        found = bool(scored["found"]) if isinstance(scored, dict) else None
        iou = float(scored["iou"]) if isinstance(scored, dict) and scored.get("iou") is not None else None
        notes.append("older heatmap file: verdict from the record" if found is not None else
                     "older heatmap file: no verdict (the record has no score for this query)")
    if "gt_box" in data:
        gt = _box_xy(data["gt_box"])
    else:
        gt, why = _scene_object_box(record, query_rec, name)
        notes.append(why)
    answer = None
    if "answer_indices" in data and np.size(data["answer_indices"]):
        sel = points[np.asarray(data["answer_indices"], dtype=np.int64)]
        answer = np.stack([sel[:, :2].min(axis=0), sel[:, :2].max(axis=0)])
    if "scene_box" in data:
        box = np.asarray(data["scene_box"], dtype=np.float64).reshape(2, 3)
        keep = points[:, 2] >= box[0, 2] - 0.02
        crop = box[:, :2]
    else:
        keep = points[:, 2] > _FLOOR_Z
        if not keep.any():
            keep[:] = True
        crop = np.stack([np.percentile(points[keep, :2], 0.5, axis=0), np.percentile(points[keep, :2], 99.5, axis=0)])
        notes.append("crop: the points above the floor")
    points, values = points[keep], values[keep]  # the floor under and around the table is left out
    for box in (gt, answer):
        if box is not None:
            crop = np.stack([np.minimum(crop[0], box[0]), np.maximum(crop[1], box[1])])
    crop = crop + np.array([[-_MARGIN], [_MARGIN]])
    return HeatmapView(points, values, name, crop, gt, answer, found, iou, right_iou, notes)


def heatmap_figures(items, w) -> list:
    """Up to :data:`MAX_HEATMAPS` query heatmaps of the records (``(record, run folder)`` pairs)
    with ``extras.heatmap_npz``, wrong and right answers alternating; a heading and a line on how
    to read them first. Empty when no record has one."""
    candidates = [(r, base) for r, base in items if (r.get("extras") or {}).get("heatmap_npz")]
    if not candidates:
        return []

    def right(r):  # from the record, before any file is read: wrong answers first
        q = _first_text_query(r)
        t = (q or {}).get("text")
        return isinstance(t, dict) and bool(t.get("found")) and (t.get("iou") or 0) > _RIGHT_IOU

    wrong = [c for c in candidates if not right(c[0])]
    good = [c for c in candidates if right(c[0])]
    order = [c for pair in zip(wrong, good) for c in pair] + wrong[len(good):] + good[len(wrong):]
    blocks, drawn = [], 0
    for r, base in order:
        ref = r["extras"]["heatmap_npz"]
        if drawn >= MAX_HEATMAPS:
            w.skip(f"heatmap of {r['episode_id']} ({r['agent']})", f"only {MAX_HEATMAPS} are drawn")
            continue
        path = Path(ref)
        if not path.is_absolute() and base is not None:
            path = base / path
        try:
            view = read_heatmap(path, r)
            png = report_plots.heatmap_topdown(
                view.points_n3, view.values_n, title=f'"{view.query}"  ({r["episode_id"]}, {r["encoder"]})',
                crop_xy=view.crop_xy, gt_box_xy=view.gt_box_xy, gt_label=f"ground truth: {view.query}",
                answer_box_xy=view.answer_box_xy, verdict=view.verdict(), verdict_ok=view.right,
                note="; ".join(view.notes))
        except (OSError, KeyError, ValueError) as exc:
            w.skip(f"heatmap {ref} ({r['episode_id']})", f"{type(exc).__name__}: {exc}")
            continue
        name = w.figure(f"heatmap_{r['suite']}_{r['episode_id']}_{r['seed']}", png)
        blocks.append(Figure(name, f'query heatmap of "{view.query}", {r["episode_id"]}: {view.verdict()}'))
        drawn += 1
    if not blocks:
        return []
    return [Heading(2, "Query heatmaps"),
            Paragraph("Each map's relevancy to its first text query, seen from above over the table: the brightest "
                      "point of each cell. Green box: the queried object; dashed: the region the map answered with. "
                      f"Right means found with IoU above {_RIGHT_IOU:g} with the object's points (older files: the record's score).")] + blocks
