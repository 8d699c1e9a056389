"""The ``spatial`` map suite (the paper's "3D lifting" comparison): spatial questions from the
ground-truth scene graph, answered from a fused 3D map and from a single RGB-D frame.

**Task**: questions of four types are generated per scene from the scene graph (objects with a
unique name that the scan sees: at least 50 labelled pixels over the scan at 160 x 120,
the same share of the image at other sizes, and at least 30 in one frame):

* ``distance``: "how far is the A from the B?"; truth: distance of the box centres;
* ``relative``: "is the A to the left/right of the B?", seen along the scan's first camera
  forward direction (:func:`conceptfusion.spatial.comparators.is_to_the_left`'s viewer convention); only
  pairs at least 0.1 m apart sideways, so the truth is not a coin toss;
* ``support``: "is the A on top of the B?"; true cases from ``supported_by`` where B's box top
  is the resting surface (a shelf's lower level is not its box top, so the box comparator
  could not say yes), B an object, furniture or the table; false cases pair A with another
  object or furniture piece of its room;
* ``containment``: "is the A inside the B?"; true cases from ``inside`` (objects in bowls,
  objects in furniture), false cases pair A with a bowl, another object or furniture.

Furniture and the table are named in the questions; the oracle knows them because its labels
include furniture and the table (privileged, like all oracle results).

**Method**: each question goes through the pattern parser (so the whole pipeline is scored),
both noun phrases are located with the mapper (best region, or not found) and the parsed
comparator is called (containment with an open top, as the scene graph defines it). ``3d``:
the map fused from the whole scan; ``2.5d``: the scan frame where both objects are most
visible (largest smaller pixel count), fused alone.

**Scoring**: accuracy per type (distance: correct when |d - d_gt| <= max(0.1 m, 20% of
d_gt); unparsed, not found or undecided answers are wrong), overall accuracy, not-found rate.
"""

from __future__ import annotations

import time
import zlib

import numpy as np

from agents.builtin import make_mapper
from harness.maps.scan import SceneScan, fuse_frames, load_shipped_scene, scan_scene

__all__ = ["QUESTION_TYPES", "METHODS", "generate_questions", "answer_questions", "run_spatial_scene", "distance_ok"]

QUESTION_TYPES = ("distance", "relative", "support", "containment")
METHODS = {"3d": "map-3d", "2.5d": "frame-2.5d"}
"""Method -> the agent name its records carry."""
_PER_SCENE = {"distance": 4, "relative": 4, "support": (2, 2), "containment": (2, 2)}
_UP = np.array([0.0, 0.0, 1.0])


def distance_ok(answer: float | None, truth: float) -> bool:
    """Whether a distance answer is within max(0.1 m, 20%) of the truth (None: wrong)."""
    return answer is not None and abs(float(answer) - truth) <= max(0.1, 0.2 * truth)


def _entities(scan: SceneScan) -> dict[str, dict]:
    """Askable things by id: visible objects with unique names, furniture, the table."""
    n_labels = max(scan.label_names) + 1
    per_frame = np.stack([np.bincount(f.segmentation[f.segmentation >= 0], minlength=n_labels)[:n_labels] for f in scan.frames])
    # seen well enough to form a region (the mapper needs 20 points) in at least one frame
    counts = np.where(per_frame.max(axis=0) >= 30, per_frame.sum(axis=0), 0)
    h, w = scan.frames[0].segmentation.shape
    min_px = max(10, int(0.0026 * h * w))  # 50 pixels at 160 x 120
    names = [v for v in scan.label_names.values()]
    n = scan.num_objects
    out = {}
    for i, o in enumerate(scan.scene.objects):
        if counts[i] >= min_px and names.count(o.name) == 1:
            room = scan.graph["objects"][i].get("room")
            out[o.id] = {"name": o.name, "label": i, "box": scan.object_boxes[i], "room": room, "kind": "object", "category": o.category}
    for j, f in enumerate(scan.graph.get("furniture", [])):
        if counts[n + j] >= min_px and names.count(f["name"]) == 1:
            out[f["id"]] = {"name": f["name"], "label": n + j, "box": np.asarray(f["aabb"]), "room": f["room"], "kind": "furniture"}
    t = scan.scene.table
    if t is not None:
        c, s = np.asarray(t.center), np.asarray(t.size)
        label = next(k for k, v in scan.label_names.items() if v == "table")
        out["table"] = {"name": "table", "label": label, "box": np.stack([c - s / 2, c + s / 2]), "room": None, "kind": "table"}
    return out


def _q(kind: str, text: str, a: dict, b: dict, truth) -> dict:
    return {"type": kind, "question": text, "a": a["name"], "b": b["name"], "labels": [int(a["label"]), int(b["label"])],
            "gt": truth if isinstance(truth, bool) else round(float(truth), 4)}


def _pick(rng, items: list, k: int) -> list:
    if len(items) <= k:
        return list(items)
    return [items[i] for i in sorted(rng.choice(len(items), size=k, replace=False))]


def generate_questions(scan: SceneScan, seed: int = 0) -> list[dict]:
    """Questions for one scanned scene (see the module docstring); deterministic in ``seed``.

    Each question: ``type``, ``question`` text, ``a`` / ``b`` names, ``labels`` (their label
    ids), ``gt`` (metres or bool).
    """
    rng = np.random.default_rng([int(seed), zlib.crc32(scan.scene.id.encode())])
    ent = _entities(scan)
    objs = [k for k, e in ent.items() if e["kind"] == "object"]
    centre = {k: e["box"].mean(axis=0) for k, e in ent.items()}
    pairs = [(a, b) for a in objs for b in objs if a < b and ent[a]["room"] == ent[b]["room"]]
    qs: list[dict] = []
    for a, b in _pick(rng, pairs, _PER_SCENE["distance"]):
        qs.append(_q("distance", f"how far is the {ent[a]['name']} from the {ent[b]['name']}?", ent[a], ent[b],
                     float(np.linalg.norm(centre[a] - centre[b]))))
    fwd = scan.frames[0].cam_to_world[:3, 2]
    fwd_h = fwd - (fwd @ _UP) * _UP
    left = -np.cross(fwd_h / np.linalg.norm(fwd_h), _UP)
    lateral = [(a, b) for a, b in pairs if abs((centre[a] - centre[b]) @ left) >= 0.1]
    for a, b in _pick(rng, lateral, _PER_SCENE["relative"]):
        side = "left" if rng.random() < 0.5 else "right"
        offset = float((centre[a] - centre[b]) @ left)
        qs.append(_q("relative", f"is the {ent[a]['name']} to the {side} of the {ent[b]['name']}?", ent[a], ent[b],
                     (offset > 0) == (side == "left")))
    support = {a: b for a, b in scan.graph["supported_by"] if a in ent}
    true_sup = [(a, b) for a, b in support.items() if b in ent and abs(ent[a]["box"][0, 2] - ent[b]["box"][1, 2]) <= 0.03]
    others = [k for k, e in ent.items() if e["kind"] in ("object", "furniture")]
    false_sup = [(a, b) for a in support for b in others if b != a and b != support[a] and ent[b]["room"] == ent[a]["room"]
                 and ent[b]["box"][1, 2] < ent[a]["box"][0, 2] + 0.5]
    n_true, n_false = _PER_SCENE["support"]
    for (a, b), truth in [(p, True) for p in _pick(rng, true_sup, n_true)] + [(p, False) for p in _pick(rng, false_sup, n_false)]:
        qs.append(_q("support", f"is the {ent[a]['name']} on top of the {ent[b]['name']}?", ent[a], ent[b], truth))
    inside = {(a, b) for a, b in scan.graph["inside"]}
    true_in = sorted((a, b) for a, b in inside if a in ent and b in ent)
    containers = [k for k in others if ent[k]["kind"] == "furniture" or ent[k].get("category") in ("bowl", "box")]
    false_in = [(a, b) for a in objs for b in containers if a != b and (a, b) not in inside and ent[b]["room"] == ent[a]["room"]]
    n_true, n_false = _PER_SCENE["containment"]
    for (a, b), truth in [(p, True) for p in _pick(rng, true_in, n_true)] + [(p, False) for p in _pick(rng, false_in, n_false)]:
        qs.append(_q("containment", f"is the {ent[a]['name']} inside the {ent[b]['name']}?", ent[a], ent[b], truth))
    return qs


def _answer(mapper, parser, q: dict, viewing_direction: np.ndarray) -> dict:
    from conceptfusion.spatial.comparators import get_comparator

    parsed = parser.parse(q["question"])
    if not parsed.ok:
        return {"parsed": None, "answer": None, "found": False, "correct": False, "reason": parsed.reason}
    a, b = parsed.arguments
    regions = []
    for name in (a, b):
        res = mapper.locate(name)
        regions.append(res.regions[0] if res.found else None)
    kwargs: dict = {"names": (a, b)}
    if parsed.function in ("isToTheLeft", "isToTheRight"):
        kwargs["viewing_direction"] = viewing_direction
    if parsed.function == "isContained":
        kwargs["open_top"] = True
    ans = get_comparator(parsed.function)(regions[0], regions[1], **kwargs)
    value = ans.value
    if q["type"] == "distance":
        correct = value is not None and not isinstance(value, bool) and distance_ok(value, q["gt"])
    else:
        correct = isinstance(value, bool) and value == q["gt"]
    return {"parsed": parsed.signature, "answer": value if value is None or isinstance(value, bool) else round(float(value), 4),
            "found": ans.found, "correct": bool(correct), "reason": ans.reason[:160]}


def answer_questions(scan: SceneScan, questions: list[dict], method: str, encoder: str) -> list[dict]:
    """Answer each question with ``method`` (``"3d"`` or ``"2.5d"``); returns the questions
    with ``parsed``, ``answer``, ``found``, ``correct``, ``reason`` (and ``frame`` for 2.5d)."""
    from agents.spatial.parser import make_parser

    if method not in METHODS:
        raise ValueError(f"spatial method: expected one of {list(METHODS)}, got {method!r}")
    parser = make_parser("pattern")
    view = scan.frames[0].cam_to_world[:3, 2].copy()
    out: list[dict] = []
    if method == "3d":
        mapper = fuse_frames(make_mapper(encoder, "rgbd"), scan)
        return [{**q, **_answer(mapper, parser, q, view)} for q in questions]
    mapper = make_mapper(encoder, "rgbd", persistent=False)
    counts = np.stack([[np.bincount(f.segmentation[f.segmentation >= 0], minlength=max(scan.label_names) + 1)[lab] for lab in range(max(scan.label_names) + 1)]
                       for f in scan.frames])  # (frames, labels)
    best = {}
    for k, q in enumerate(questions):
        la, lb = q["labels"]
        score = np.minimum(counts[:, la], counts[:, lb]) * 10**6 + counts[:, la] + counts[:, lb]
        best[k] = int(np.argmax(score))
    out = [None] * len(questions)
    for fi in sorted(set(best.values())):
        fuse_frames(mapper, scan, [scan.frames[fi]])
        for k in (k for k, f in best.items() if f == fi):
            out[k] = {**questions[k], **_answer(mapper, parser, questions[k], view), "frame": fi}
    return out


def run_spatial_scene(
    scene_id: str, method: str, encoder: str, *, frames: int | None = None, width: int = 160, height: int = 120, seed: int = 0,
) -> tuple[dict, dict, dict]:
    """One scene, one method; returns ``(metrics, extras, timings)``. ``frames`` defaults to
    12 for tabletop scenes and 8 per room for household scenes."""
    t0 = time.perf_counter()
    scene = load_shipped_scene(scene_id)
    n = frames if frames is not None else (8 * len(scene.rooms) if scene.rooms else 12)
    scan = scan_scene(scene, frames=n, width=width, height=height)
    questions = generate_questions(scan, seed)
    t_scan = time.perf_counter() - t0
    answered = answer_questions(scan, questions, method, encoder)
    metrics: dict = {}
    for kind in QUESTION_TYPES:
        sub = [q for q in answered if q["type"] == kind]
        metrics[f"acc_{kind}"] = float(np.mean([q["correct"] for q in sub])) if sub else None
        metrics[f"n_{kind}"] = len(sub)
    metrics["accuracy"] = float(np.mean([q["correct"] for q in answered])) if answered else None
    metrics["notfound_rate"] = float(np.mean([not q["found"] for q in answered])) if answered else None
    metrics["parse_fail_rate"] = float(np.mean([q["parsed"] is None for q in answered])) if answered else None
    for q in answered:
        q.pop("labels", None)
    extras = {"questions": answered, "frames": n, "image_size": [width, height], "privileged": encoder == "oracle"}
    timings = {"scan_s": t_scan, "answer_s": time.perf_counter() - t0 - t_scan}
    return metrics, extras, timings
