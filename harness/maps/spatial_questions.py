"""Spatial questions from a scanned scene's ground truth, one per (comparator, pair, template).

What can be asked (:func:`askable`): objects with a unique name that the scan sees (at least
50 labelled pixels over the scan at 160 x 120, the same share of the image at other sizes, and
at least 30 in one frame), furniture seen as well, and the table. Per scene and comparator at
most :data:`PER_SCENE` questions; for the yes/no comparators half true and half false where the
scene allows. Every truth is the comparator's own definition applied to ground-truth boxes and
sizes, on pairs where the answer is clear-cut:

* ``howFar``: two objects of one room; truth: distance of their box centres (metres);
* ``isToTheLeft`` / ``isToTheRight``: two objects of one room at least 0.1 m apart sideways,
  seen along the scan's first camera forward direction (the suite's viewer);
* ``onTopOf``: true cases from ``supported_by`` where B's box top is the resting surface (a
  shelf's lower level is not its box top), B an object, furniture or the table; false cases
  pair A with another object or furniture piece of its room whose top is below A's bottom
  + 0.5 m;
* ``under``: the same pairs the other way round ("is the B under the A");
* ``isBigger``: two objects of one room (then an object and furniture or the table) whose size
  volumes differ at least twofold;
* ``canFitInside``: an object and another object or furniture piece of its room; true when
  every sorted size of A plus 1 cm clearance is at least 2 cm below B's, false when one
  exceeds B's by at least 2 cm;
* ``isContained``: true cases from ``inside`` (objects in bowls, in furniture), false cases
  pair A with a receptacle (:data:`RECEPTACLES`: a bowl, a box, a basket...) or furniture of its
  room.

Each question is phrased by one template of its comparator (:mod:`harness.maps.spatial_templates`),
the templates taken in a seeded order so a scene uses different ones.
"""

from __future__ import annotations

import zlib

import numpy as np

from conceptfusion.spatial.comparators import COMPARATOR_NAMES
from harness.maps.scan import SceneScan
from harness.maps.spatial_templates import SpatialTemplate, load_templates

__all__ = ["QUESTION_TYPES", "PER_SCENE", "RECEPTACLES", "askable", "generate_questions"]

QUESTION_TYPES = COMPARATOR_NAMES
"""A question's ``type``: the comparator it asks (the paper's eight)."""

PER_SCENE = 4
"""Most questions per comparator and scene."""

_UP = np.array([0.0, 0.0, 1.0])
_MIN_LATERAL = 0.1  # metres sideways between the two centres of a left/right question
_MIN_VOLUME_RATIO = 2.0
_FIT_CLEARANCE = 0.01  # the comparator's default clearance
_FIT_MARGIN = 0.02

RECEPTACLES = ("bowl", "box", "basket", "crate", "bucket", "trash can")
"""Object categories a false ``isContained`` question may name as the container: open-topped things
other objects are put in (v1: bowls and boxes; the object library adds baskets, crates, buckets and
trash cans)."""


def askable(scan: SceneScan) -> dict[str, dict]:
    """Askable things by id (see the module docstring), each with ``name``, ``kind``
    (``"object"``, ``"furniture"``, ``"table"``), ``box`` (2, 3), ``size`` (3,) sorted largest
    first, ``room`` and, for objects, ``category``. Ground truth: for making questions only."""
    n_labels = max(scan.label_names) + 1
    per_frame = np.stack([np.bincount(f.segmentation[f.segmentation >= 0], minlength=n_labels)[:n_labels] for f in scan.frames])
    # seen well enough to form a region (the mapper needs 20 points) in at least one frame
    counts = np.where(per_frame.max(axis=0) >= 30, per_frame.sum(axis=0), 0)
    h, w = scan.frames[0].segmentation.shape
    min_px = max(10, int(0.0026 * h * w))  # 50 pixels at 160 x 120
    names = list(scan.label_names.values())
    n = scan.num_objects
    out = {}
    for i, o in enumerate(scan.scene.objects):
        if counts[i] >= min_px and names.count(o.name) == 1:
            out[o.id] = {"name": o.name, "box": scan.object_boxes[i], "size": _sorted(o.size), "room": scan.graph["objects"][i].get("room"),
                         "kind": "object", "category": o.category}
    for j, f in enumerate(scan.graph.get("furniture", [])):
        if counts[n + j] >= min_px and names.count(f["name"]) == 1:
            box = np.asarray(f["aabb"])
            size = scan.scene.furniture[j].size if j < len(scan.scene.furniture) else box[1] - box[0]
            out[f["id"]] = {"name": f["name"], "box": box, "size": _sorted(size), "room": f["room"], "kind": "furniture"}
    t = scan.scene.table
    if t is not None:
        c, s = np.asarray(t.center), np.asarray(t.size)
        out["table"] = {"name": "table", "box": np.stack([c - s / 2, c + s / 2]), "size": _sorted(s), "room": None, "kind": "table"}
    return out


def _sorted(size) -> np.ndarray:
    return np.sort(np.asarray(size, np.float64))[::-1]


def _pick(rng: np.random.Generator, items: list, k: int) -> list:
    if len(items) <= k:
        return list(items)
    return [items[i] for i in sorted(rng.choice(len(items), size=k, replace=False))]


def _balanced(rng: np.random.Generator, true: list, false: list, k: int) -> list[tuple[tuple, bool]]:
    """Up to ``k // 2`` true and ``k - k // 2`` false pairs (more of one kind when the other runs short)."""
    t = _pick(rng, true, k // 2)
    f = _pick(rng, false, k - len(t))
    t += _pick(rng, [p for p in true if p not in t], k - len(t) - len(f))
    return [(p, True) for p in t] + [(p, False) for p in f]


def _oriented(rng: np.random.Generator, pairs: list, k: int, truth) -> list[tuple[tuple, bool]]:
    """``k`` pairs, each ordered so that about half of them make ``truth(a, b)`` true."""
    out = []
    for n, (a, b) in enumerate(_pick(rng, pairs, k)):
        want = n % 2 == 0
        out.append(((a, b), want) if truth(a, b) == want else ((b, a), want))
    return out


def _cases(scan: SceneScan, ent: dict[str, dict], rng: np.random.Generator) -> dict[str, list[tuple[tuple[str, str], object]]]:
    """Per comparator: ((a id, b id), truth) cases."""
    objs = [k for k, e in ent.items() if e["kind"] == "object"]
    others = [k for k, e in ent.items() if e["kind"] in ("object", "furniture")]
    furniture = [k for k, e in ent.items() if e["kind"] == "furniture"]
    centre = {k: e["box"].mean(axis=0) for k, e in ent.items()}
    pairs = [(a, b) for a in objs for b in objs if a < b and ent[a]["room"] == ent[b]["room"]]
    out: dict[str, list] = {}
    out["howFar"] = [(p, float(np.linalg.norm(centre[p[0]] - centre[p[1]]))) for p in _pick(rng, pairs, PER_SCENE)]

    fwd = scan.frames[0].cam_to_world[:3, 2]
    fwd_h = fwd - (fwd @ _UP) * _UP
    left = -np.cross(fwd_h / np.linalg.norm(fwd_h), _UP)
    lateral = [(a, b) for a, b in pairs if abs((centre[a] - centre[b]) @ left) >= _MIN_LATERAL]
    out["isToTheLeft"] = _oriented(rng, lateral, PER_SCENE, lambda a, b: float((centre[a] - centre[b]) @ left) > 0)
    out["isToTheRight"] = _oriented(rng, lateral, PER_SCENE, lambda a, b: float((centre[a] - centre[b]) @ left) < 0)

    support = {a: b for a, b in scan.graph["supported_by"] if a in ent}
    true_sup = [(a, b) for a, b in support.items() if b in ent and abs(ent[a]["box"][0, 2] - ent[b]["box"][1, 2]) <= 0.03]
    false_sup = [(a, b) for a in support for b in others if b != a and b != support[a] and ent[b]["room"] == ent[a]["room"]
                 and ent[b]["box"][1, 2] < ent[a]["box"][0, 2] + 0.5]
    out["onTopOf"] = _balanced(rng, true_sup, false_sup, PER_SCENE)
    out["under"] = [((b, a), truth) for (a, b), truth in _balanced(rng, true_sup, false_sup, PER_SCENE)]

    volume = {k: float(np.prod(e["size"])) for k, e in ent.items()}
    differ = [(a, b) for a, b in pairs if max(volume[a], volume[b]) >= _MIN_VOLUME_RATIO * min(volume[a], volume[b])]
    with_furniture = [(a, b) for a in objs for b in furniture + ["table"] * ("table" in ent) if ent[a]["room"] == ent[b]["room"]]
    big = _oriented(rng, differ, PER_SCENE, lambda a, b: volume[a] > volume[b])
    if len(big) < PER_SCENE:
        big += _oriented(rng, with_furniture, PER_SCENE - len(big), lambda a, b: volume[a] > volume[b])
    out["isBigger"] = big

    def fit_margin(a: str, b: str) -> float:
        return float(np.min(ent[b]["size"] - ent[a]["size"] - _FIT_CLEARANCE))

    fit_pairs = [(a, b) for a in objs for b in others if a != b and ent[a]["room"] == ent[b]["room"]]
    out["canFitInside"] = _balanced(rng, [p for p in fit_pairs if fit_margin(*p) >= _FIT_MARGIN],
                                    [p for p in fit_pairs if fit_margin(*p) <= -_FIT_MARGIN], PER_SCENE)

    inside = {(a, b) for a, b in scan.graph["inside"]}
    true_in = sorted((a, b) for a, b in inside if a in ent and b in ent)
    containers = [k for k in others if ent[k]["kind"] == "furniture" or ent[k].get("category") in RECEPTACLES]
    false_in = [(a, b) for a in objs for b in containers if a != b and (a, b) not in inside and ent[b]["room"] == ent[a]["room"]]
    out["isContained"] = _balanced(rng, true_in, false_in, PER_SCENE)
    return out


def generate_questions(scan: SceneScan, seed: int = 0, templates: dict[str, tuple[SpatialTemplate, ...]] | None = None) -> list[dict]:
    """Questions for one scanned scene (see the module docstring); deterministic in ``seed``.

    ``templates`` defaults to :func:`~harness.maps.spatial_templates.load_templates`. Each
    question: ``type`` (the comparator), ``question`` (the filled template), ``template`` (its
    id), ``fresh``, ``a`` / ``b`` (names), ``expected`` (the call, ``"onTopOf(a, b)"``), ``gt``
    (metres or bool).
    """
    templates = load_templates() if templates is None else templates
    rng = np.random.default_rng([int(seed), zlib.crc32(scan.scene.id.encode())])
    ent = askable(scan)
    cases = _cases(scan, ent, rng)
    qs: list[dict] = []
    for comparator in QUESTION_TYPES:
        order = rng.permutation(len(templates[comparator]))
        for k, ((a, b), truth) in enumerate(cases[comparator]):
            t = templates[comparator][int(order[k % len(order)])]
            na, nb = ent[a]["name"], ent[b]["name"]
            qs.append({"type": comparator, "question": t.fill(na, nb), "template": t.id, "fresh": t.fresh, "a": na, "b": nb,
                       "expected": f"{comparator}({na}, {nb})",
                       "gt": truth if isinstance(truth, bool) else round(float(truth), 4)})
    return qs
