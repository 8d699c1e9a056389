"""The ``spatial`` map suite (the paper's "3D lifting" comparison): spatial questions from the
ground-truth scene graph in many phrasings, read by a spatial-question parser and answered from
a fused 3D map and from a single RGB-D frame.

**Task**: per scene, up to four questions for each of the paper's eight comparators, made from
the scene graph and phrased by paraphrase templates (:mod:`harness.maps.spatial_questions`,
:mod:`harness.maps.spatial_templates`; a share of the templates phrased unlike anything the
parsers were developed on). Furniture and the table are named too; the oracle knows them
because its labels include them (privileged, like all oracle results).

**Method**: each question goes through the parser (``"semantic"`` by default, so parser errors
count), each noun phrase of the parsed call is located with the mapper (best region, or not
found) and the parsed comparator is called (containment with an open top, as the scene graph
defines it; left/right seen along the scan's first camera direction). ``3d``: the map fused
from the whole scan. ``2.5d``: one scan frame fused alone, chosen from what the agent has: every
frame is fused on its own, both parsed noun phrases are located in it with the same perception,
and the frame kept is the one where both are found, then where the lower of their two best
median scores is highest (to 0.01), then where the smaller of the two regions has the most
points. Both use the perception's score floor for the scene's setting (tabletop, or
household for apartments: :func:`~conceptfusion.perception.featurizer.score_floor_for`), and
both take the question's objects to be there (options ``assume_present`` and
``name_only_fallback``, on by default: a noun phrase the floor rejects is located by its best
region anyway, :meth:`~agents.concept_map.ConceptMapper.locate_present`). No ground-truth label or segmentation is read by either method unless the perception
itself is the privileged oracle.

**Scoring**: a question is correct when the answer matches the truth (distance: |d - d_gt| <=
max(0.1 m, 20% of d_gt)); refused or wrong parses, not found or undecided answers are wrong.
The parse is right when it is the expected call or an equivalent one (``under(a, b)`` is
``onTopOf(b, a)``, ``isToTheLeft(a, b)`` is ``isToTheRight(b, a)``), comparing arguments after
:func:`agents.spatial.parser.clean_noun_phrase`. Chance references beside them, on the same
questions: ``chance_always_yes`` (every yes/no question answered yes, every distance wrong) and
``chance_random`` (the expected accuracy of a fair coin on the yes/no questions, every distance
wrong). Metrics: ``accuracy`` (end to end),
``accuracy_parsed`` (over the questions parsed right), ``parse_rate``, ``parse_fail_rate``
(refused), ``notfound_rate`` (over the questions parsed right), ``accuracy_fresh`` /
``accuracy_seen`` (fresh vs common templates), ``acc_<comparator>`` and ``n_<comparator>``.
"""

from __future__ import annotations

import time

import numpy as np

from agents.builtin import make_mapper
from agents.spatial.parser import clean_noun_phrase, make_parser
from conceptfusion.perception.featurizer import is_oracle
from conceptfusion.spatial.comparators import get_comparator
from harness.maps.scan import SceneScan, fuse_frames, load_shipped_scene, scan_scene
from harness.maps.spatial_questions import PER_SCENE, QUESTION_TYPES, askable, generate_questions
from sim_envs.scenes.format import Scene

__all__ = [
    "QUESTION_TYPES", "PER_SCENE", "METHODS", "DEFAULT_PARSER", "SUITE_PARSERS", "generate_questions", "askable", "parse_outcome",
    "answer_questions", "run_spatial_scene", "score_spatial_scene", "distance_ok", "spatial_metrics",
]

METHODS = {"3d": "map-3d", "2.5d": "frame-2.5d"}
"""Method -> the agent name its records carry."""

DEFAULT_PARSER = "semantic"
"""The parser backend the suite reads questions with (:func:`agents.spatial.parser.make_parser`)."""

SUITE_PARSERS = ("semantic", "pattern")
"""The offline parser backends the suite's ``parser`` option accepts."""

_EQUIVALENT = {"under": "onTopOf", "onTopOf": "under", "isToTheLeft": "isToTheRight", "isToTheRight": "isToTheLeft"}


def distance_ok(answer: float | None, truth: float) -> bool:
    """Whether a distance answer is within max(0.1 m, 20%) of the truth (None: wrong)."""
    return answer is not None and abs(float(answer) - truth) <= max(0.1, 0.2 * truth)


def parse_outcome(parsed, question: dict) -> str:
    """``"exact"``, ``"equivalent"`` (the same relation with swapped arguments), ``"wrong"`` or
    ``"refused"``: how a :class:`~agents.spatial.signature.ParseResult` compares with the
    question's expected call (``type``, ``a``, ``b``)."""
    if not parsed.ok:
        return "refused"
    got = tuple(clean_noun_phrase(x) for x in parsed.arguments)
    want = (clean_noun_phrase(question["a"]), clean_noun_phrase(question["b"]))
    if parsed.function == question["type"] and got == want:
        return "exact"
    if parsed.function == _EQUIVALENT.get(question["type"]) and got == want[::-1]:
        return "equivalent"
    return "wrong"


def _regions(results: dict, parsed) -> list:
    return [results[name].regions[0] if results[name].found else None for name in parsed.arguments]


def _answer(q: dict, parsed, results: dict, viewing_direction: np.ndarray) -> dict:
    """Score one question given its parse and the located noun phrases (name -> QueryResult)."""
    outcome = parse_outcome(parsed, q)
    if not parsed.ok:
        return {"parsed": None, "parse": outcome, "answer": None, "found": False, "correct": False, "reason": parsed.reason[:160]}
    a, b = parsed.arguments
    kwargs: dict = {"names": (a, b)}
    if parsed.function in ("isToTheLeft", "isToTheRight"):
        kwargs["viewing_direction"] = viewing_direction
    if parsed.function == "isContained":
        kwargs["open_top"] = True
    ans = get_comparator(parsed.function)(*_regions(results, parsed), **kwargs)
    value = ans.value
    if outcome == "wrong":
        correct = False
    elif q["type"] == "howFar":
        correct = value is not None and not isinstance(value, bool) and distance_ok(value, q["gt"])
    else:
        correct = isinstance(value, bool) and value == q["gt"]
    return {"parsed": parsed.signature, "parse": outcome,
            "answer": value if value is None or isinstance(value, bool) else round(float(value), 4),
            "found": ans.found, "correct": bool(correct), "reason": ans.reason[:160]}


def _locate(mapper, name: str, assume_present: bool, name_only: bool):
    """The mapper's answer for a noun phrase of a question; with ``assume_present`` on the
    question's presupposition that the object is there
    (:meth:`~agents.concept_map.ConceptMapper.locate_present`, ``name_only`` its last fallback)."""
    return mapper.locate_present(name, name_only=name_only) if assume_present else mapper.locate(name)


def _frame_key(results: dict, names: tuple[str, str]) -> tuple:
    """How well one frame shows both names, from the frame's own located regions (higher is better)."""
    found = [results[n].regions[0] for n in names if results[n].found]
    if len(found) < len(names):
        return (len(found), -np.inf, 0)
    return (len(found), round(min(float(np.median(r.scores_n)) for r in found), 2), min(len(r.points_n3) for r in found))


def answer_questions(scan: SceneScan, questions: list[dict], method: str, encoder: str, *, parser: str = DEFAULT_PARSER,
                     setting: str = "tabletop", assume_present: bool = True, name_only_fallback: bool = True,
                     mapper=None) -> list[dict]:
    """Answer each question with ``method`` (``"3d"`` or ``"2.5d"``) and the parser backend
    ``parser``; returns the questions with ``parsed``, ``parse``, ``answer``, ``found``,
    ``correct``, ``reason`` (and ``frame`` for 2.5d). ``setting`` (``"tabletop"`` or
    ``"household"``: where the robot works, as its operator would configure it) picks the
    perception's score floor. ``assume_present``: a question presupposes the objects it names,
    so a noun phrase the score floor rejects is located by its best region without the floor,
    and with ``name_only_fallback`` by the region scoring highest for it alone when no region
    beats the generic phrases (the pushers' rule, :meth:`~agents.concept_map.ConceptMapper.locate_present`);
    False: such a phrase is "not found" and the question wrong.

    Reads the scan's frames (RGB-D and pose); the label images and names only when the
    perception is privileged (:func:`~harness.maps.scan.fuse_frames`). ``mapper``: for ``"3d"``,
    a mapper that has fused the scan already (``encoder`` is then only its name).
    """
    if method not in METHODS:
        raise ValueError(f"spatial method: expected one of {list(METHODS)}, got {method!r}")
    reader = make_parser(parser)
    view = scan.frames[0].cam_to_world[:3, 2].copy()
    parses = [reader.parse(q["question"]) for q in questions]
    names = sorted({n for p in parses if p.ok for n in p.arguments})
    if method == "3d":
        mapper = mapper if mapper is not None else fuse_frames(make_mapper(encoder, "rgbd", setting=setting), scan)
        results = {n: _locate(mapper, n, assume_present, name_only_fallback) for n in names}
        return [{**q, **_answer(q, p, results, view)} for q, p in zip(questions, parses)]
    mapper = make_mapper(encoder, "rgbd", persistent=False, setting=setting)
    per_frame = []
    for frame in scan.frames:
        fuse_frames(mapper, scan, [frame])
        per_frame.append({n: _locate(mapper, n, assume_present, name_only_fallback) for n in names})
    out = []
    for q, p in zip(questions, parses):
        if not p.ok:
            out.append({**q, **_answer(q, p, {}, view), "frame": None})
            continue
        keys = [_frame_key(res, tuple(p.arguments)) for res in per_frame]
        best = max(range(len(keys)), key=lambda i: (keys[i], -i))
        out.append({**q, **_answer(q, p, per_frame[best], view), "frame": best})
    return out


def _mean(flags: list) -> float | None:
    return float(np.mean(flags)) if flags else None


def spatial_metrics(answered: list[dict]) -> dict:
    """The suite's metrics of answered questions (see the module docstring)."""
    parsed_right = [q for q in answered if q["parse"] in ("exact", "equivalent")]
    metrics: dict = {"n_questions": len(answered)}
    for kind in QUESTION_TYPES:
        sub = [q["correct"] for q in answered if q["type"] == kind]
        metrics[f"acc_{kind}"] = _mean(sub)
        metrics[f"n_{kind}"] = len(sub)
    metrics["accuracy"] = _mean([q["correct"] for q in answered])
    metrics["accuracy_parsed"] = _mean([q["correct"] for q in parsed_right])
    metrics["parse_rate"] = _mean([q["parse"] in ("exact", "equivalent") for q in answered])
    metrics["parse_fail_rate"] = _mean([q["parse"] == "refused" for q in answered])
    metrics["notfound_rate"] = _mean([not q["found"] for q in parsed_right])
    metrics["accuracy_fresh"] = _mean([q["correct"] for q in answered if q["fresh"]])
    metrics["accuracy_seen"] = _mean([q["correct"] for q in answered if not q["fresh"]])
    yes_no = [q["gt"] for q in answered if q["type"] != "howFar"]
    metrics["chance_always_yes"] = sum(bool(g) for g in yes_no) / len(answered) if answered else None
    metrics["chance_random"] = 0.5 * len(yes_no) / len(answered) if answered else None
    return metrics


def run_spatial_scene(
    scene_id: str, method: str, encoder: str, *, frames: int | None = None, width: int = 160, height: int = 120, seed: int = 0,
    parser: str = DEFAULT_PARSER, assume_present: bool = True, name_only_fallback: bool = True,
) -> tuple[dict, dict, dict]:
    """One shipped scene, one method: :func:`score_spatial_scene` of ``load_shipped_scene(scene_id)``."""
    return score_spatial_scene(load_shipped_scene(scene_id), method, encoder, frames=frames, width=width, height=height, seed=seed,
                               parser=parser, assume_present=assume_present, name_only_fallback=name_only_fallback)


def score_spatial_scene(
    scene: Scene, method: str, encoder: str, *, frames: int | None = None, width: int = 160, height: int = 120, seed: int = 0,
    parser: str = DEFAULT_PARSER, assume_present: bool = True, name_only_fallback: bool = True,
) -> tuple[dict, dict, dict]:
    """One scene, one method: scan, questions, answers; returns ``(metrics, extras, timings)``.
    ``frames`` defaults to 12 for tabletop scenes and 8 per room for household scenes."""
    t0 = time.perf_counter()
    n = frames if frames is not None else (8 * len(scene.rooms) if scene.rooms else 12)
    scan = scan_scene(scene, frames=n, width=width, height=height)
    questions = generate_questions(scan, seed)
    t_scan = time.perf_counter() - t0
    answered = answer_questions(scan, questions, method, encoder, parser=parser,
                                setting="household" if scene.rooms else "tabletop", assume_present=assume_present,
                                name_only_fallback=name_only_fallback)
    extras = {"questions": answered, "frames": n, "image_size": [width, height], "parser": parser,
              "assume_present": assume_present, "name_only_fallback": name_only_fallback,
              "privileged": is_oracle(encoder)}
    timings = {"scan_s": t_scan, "answer_s": time.perf_counter() - t0 - t_scan}
    return spatial_metrics(answered), extras, timings
