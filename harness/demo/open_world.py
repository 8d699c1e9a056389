"""The default demo: a v2 tabletop mapped with the v2 tower and asked open-vocabulary questions.

A shipped v2 tabletop (``scenes/tabletop-v2/``, objects from the 91-category library) is rendered
along an orbit in MuJoCo, fused into a ConceptFusion map with the ``rgbd`` mask proposer and the
encoder the v2 suites use (``embedded-v2`` by default), and asked what the ``query-open`` and
``spatial-v2`` suites ask, one of each kind:

- the **name** of every object on the table ("the mug"), each marked with its split group
  (``seen``: an instance the tower trained on; ``held_out_instance``, ``held_out_category``,
  ``validation``: what it never trained on);
- a **synonym** ("the coffee mug"), a **material** ("the ceramic mug") and a **function**
  ("something to drink from"): the first query of each kind that
  :func:`harness.maps.query_open.open_queries` draws for the scene about a ``seen`` object, a
  different object for each kind where the table allows;
  these and the names are right when the best region's 3D IoU with the object's ground-truth
  points is above 0.25;
- an **absent** object (a library category nothing on the table answers to): right when not found;
- a **spatial** question ("is the mug to the left of the book?"): the scene's first question of
  :func:`harness.maps.spatial_questions.generate_questions`, parsed into a comparator
  (:mod:`agents.spatial`) and answered from the map's regions; right when the answer matches the
  simulator's (distances within max(0.1 m, 20%)).

Which queries are asked is fixed by the scene and the seed, not chosen by how they come out; the
shipped tower names only categories it was trained on (docs/model_card.md), so a query of another
scene may well fail. The map is saved with its encoder and lookup (``cfharness view`` opens it
with them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["OPEN_KINDS", "OpenOutcome", "run_open_demo"]

OPEN_KINDS = ("name", "synonym", "material", "function", "absent")
"""The query kinds the demo asks, one each, in this order (then one spatial question)."""

_ACC = 0.25  # 3D IoU above which a region counts as the object (query-open's acc25)


@dataclass(frozen=True)
class OpenOutcome:
    """One demo query and how it went against the simulator's ground truth."""

    kind: str
    """One of :data:`OPEN_KINDS` or ``"spatial"``."""
    query: str
    answer: str
    """What the map answered, in words ("found, IoU 0.62", "not found", "yes", "0.43 m")."""
    truth: str
    """What is true ("the mug", "absent", "no", "0.40 m")."""
    correct: bool
    group: str = ""
    """The split group of the object asked about (``seen``, ``held_out_instance``, ...; empty for
    absent objects and spatial questions)."""


def _pick_queries(scene, seed: int) -> list[dict]:
    """Every ``name`` query :func:`~harness.maps.query_open.open_queries` draws for the scene (one
    per object), then per other kind of :data:`OPEN_KINDS` the first it draws about a ``seen``
    object (any, when there is none), preferring one that no kind before it asked about."""
    from harness.maps.query_open import open_queries

    queries = open_queries(scene, seed)
    picked = [q for q in queries if q["kind"] == "name"]
    asked: set[str] = set()  # objects a synonym, material or function query was about
    for kind in OPEN_KINDS[1:]:
        of_kind = [q for q in queries if q["kind"] == kind]
        ranked = sorted(of_kind, key=lambda q: (q["group"] != "seen" and kind != "absent", bool(asked & set(q["objects"]))))
        if ranked:
            picked.append(ranked[0])
            asked.update(ranked[0]["objects"])
    return picked


def _spatial(scan, mapper, encoder: str, seed: int) -> OpenOutcome | None:
    from harness.maps.spatial import answer_questions
    from harness.maps.spatial_questions import generate_questions

    questions = generate_questions(scan, seed)
    if not questions:
        return None
    q = answer_questions(scan, questions[:1], "3d", encoder, mapper=mapper)[0]

    def words(v) -> str:
        return "not answered" if v is None else ("yes" if v else "no") if isinstance(v, bool) else f"{float(v):.2f} m"

    answer = words(q["answer"]) + ("" if q["found"] else f" ({q['reason']})")
    return OpenOutcome("spatial", q["question"], answer, words(q["gt"]), bool(q["correct"]))


def run_open_demo(scene_id: str, encoder: str, *, frames: int, width: int, height: int, seed: int = 0,
                  out_dir: Path | None = None) -> dict:
    """Scan ``scene_id`` (a shipped v2 tabletop), fuse a map with ``encoder``, ask the demo's
    queries (see the module docstring) and return a summary: ``scene``, ``encoder``,
    ``objects`` (the table's categories), ``num_points``, ``bytes_per_point``, ``frames``,
    ``render_s`` (the scan), ``map_s_per_frame`` (features and fusion), ``outcomes``
    (:class:`OpenOutcome`) and ``map`` (the saved map's path, with ``out_dir``).

    Raises:
        ValueError: an unknown scene id or encoder (with the valid ones).
    """
    from agents.builtin import make_mapper
    from conceptfusion.map.persistence import save_map
    from harness.maps.query import iou, select_points
    from harness.maps.query_open import load_open_scene
    from harness.maps.scan import fuse_frames, point_labels, scan_scene
    from harness.replay.record import map_meta

    scene = load_open_scene(scene_id)
    mapper = make_mapper(encoder, "rgbd", setting="tabletop")  # checks the encoder before the scan
    t0 = time.perf_counter()
    scan = scan_scene(scene, frames=frames, width=width, height=height)
    t_scan = time.perf_counter() - t0
    fuse_frames(mapper, scan)
    t_fuse = time.perf_counter() - t0 - t_scan
    points = mapper.map.points
    labels = point_labels(points, scan.object_boxes)
    index = {o.id: i for i, o in enumerate(scene.objects)}
    outcomes = []
    for q in _pick_queries(scene, seed):
        res = mapper.locate(q["text"])
        if q["kind"] == "absent":
            outcomes.append(OpenOutcome(q["kind"], q["text"], "found" if res.found else "not found", "absent",
                                        not res.found))
            continue
        truth = np.isin(labels, [index[i] for i in q["objects"]])
        names = ", ".join(sorted({o.category for o in scene.objects if o.id in q["objects"]}))
        if not res.found:
            outcomes.append(OpenOutcome(q["kind"], q["text"], f"not found ({res.reason})", names, False, q["group"]))
            continue
        region, _ = select_points(res, len(points), 0.6)
        score = iou(region, truth)
        outcomes.append(OpenOutcome(q["kind"], q["text"], f"found, IoU {score:.2f}", names, score > _ACC, q["group"]))
    spatial = _spatial(scan, mapper, encoder, seed)
    if spatial is not None:
        outcomes.append(spatial)
    summary = {
        "scene": scene.id, "encoder": encoder, "num_points": len(mapper.map),
        "bytes_per_point": mapper.map.nbytes() / max(len(mapper.map), 1), "frames": frames,
        "render_s": t_scan, "map_s_per_frame": t_fuse / max(frames, 1),
        "objects": sorted(o.category for o in scene.objects), "outcomes": outcomes,
    }
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        summary["map"] = save_map(mapper.map, out / "map.npz", meta=map_meta(mapper, "demo"))
    return summary
