"""Derive the ``oracle`` perception's score floor from the floor-calibration scenes.

The ``oracle`` labels every segment with the MiniLM text embedding (registry encoder
:data:`~conceptfusion.perception.oracle_floor.ORACLE_TEXT_ENCODER`) of its object's name, the
name the environments give in ``info["object_names"]``; every point of a segment carries exactly
that vector, so a region's median score against a query is ``cos(embed(query), embed(label))``.
The floor must accept a goal's own wording and reject every other object of the scene.

**Data.** The scenes of the regression suites' calibration episodes (``scenes/calibration/``, the
files of :data:`CALIBRATION_EPISODE_FILES`, made by ``python -m scenes.make_calibration``): 150
tabletops and 20 apartments, none of them an evaluation scene. For every object of every scene:

- *present* pairs: each wording of the object (:func:`query_wordings`: its label, and the text
  the agents pass to ``ConceptMapper.locate`` for it) against its own label;
- *near-miss* pairs: the same wordings against the label of every *other* object of the scene
  (another colour, another kind: a query must not select another object).

**Rule** (:func:`choose_oracle_floor`): a region is found when its score is ``>= floor``. When
every present score is above every near-miss score, the floor is the midpoint between the lowest
present and the highest near-miss score; otherwise it is the threshold that misclassifies the
fewest pairs (ties: the midpoint of the widest interval of such thresholds, then the lowest).

The floor and its numbers go to :data:`~conceptfusion.perception.oracle_floor.ORACLE_FLOOR_FILE`,
which :mod:`conceptfusion.perception.featurizer` reads as ``ORACLE_MIN_SCORE``::

    python -m tower_training.oracle_floor --write   # derive and write the file
    python -m tower_training.oracle_floor --check   # derive and compare; exits 1 when they differ
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from conceptfusion.errors import CalibrationFileError, MissingFileError
from conceptfusion.io_utils import atomic_write_text
from conceptfusion.perception.oracle_floor import (
    ORACLE_FLOOR_COMMAND, ORACLE_FLOOR_FILE, ORACLE_FLOOR_FORMAT, ORACLE_FLOOR_VERSION, ORACLE_TEXT_ENCODER,
    read_oracle_floor_file,
)
from conceptfusion.perception.registry import make_encoder
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes, resolve_scene

__all__ = [
    "CALIBRATION_EPISODE_FILES", "WORDINGS", "FloorChoice", "ScoredPair", "query_wordings", "calibration_scenes",
    "score_pairs", "choose_oracle_floor", "derive", "write", "check", "main",
]

CALIBRATION_EPISODE_FILES = ("calibration/tabletop-episodes-v1.jsonl", "calibration/search-episodes-v1.jsonl")
"""The regression suites' calibration episode files (relative to ``scenes/``); their scenes are
the floor-calibration scenes."""

WORDINGS = {
    "tabletop_rearrange": "the label; the name map-pusher and frame-pusher read from 'push the <name> to the <side> "
                          "of the line' (lower case, single spaces)",
    "object_search": "the label; the version-1 instruction 'the <name>', which map-navigator and frame-searcher "
                     "send as it is",
}
"""Per task, the wordings :func:`query_wordings` gives an object (recorded in the floor file)."""

_DIGITS = 6
"""Decimals of the scores and the floor in the file."""
_TOL = 1e-5
"""How far a recomputed number may be from the file's (the text tower's float noise)."""


def query_wordings(task: str, name: str) -> tuple[str, ...]:
    """The texts that ask for an object called ``name`` in ``task``: its label (``name``), then
    what the agents send to ``ConceptMapper.locate`` for it, without repeats.

    - ``tabletop_rearrange``: the pushers parse ``"push the <name> to the <side> of the line"``
      lower-cased, so they send the name lower-cased with single spaces;
    - ``object_search``: the instruction of a version-1 episode is ``"the <name>"``, sent as it is.

    Raises:
        ValueError: unknown task or empty name.
    """
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"name: expected an object name such as 'red mug', got {name!r}")
    if task == "tabletop_rearrange":
        sent = " ".join(name.lower().split())
    elif task == "object_search":
        sent = f"the {name}"
    else:
        raise ValueError(f"task: expected one of {sorted(WORDINGS)}, got {task!r}")
    return tuple(dict.fromkeys((name, sent)))


def calibration_scenes(files: Sequence[str] = CALIBRATION_EPISODE_FILES,
                       scenes_root: Path = SCENES_ROOT) -> list[tuple[str, str, list[str]]]:
    """``(task, scene path, object labels)`` of every scene the episode ``files`` use, in file
    order, then by scene path (the labels are ``info["object_names"]``: the scene's object names)."""
    out = []
    for f in files:
        episodes = load_episodes(Path(scenes_root) / f)
        refs = sorted({(e.scene, e.scene_seed) for e in episodes.episodes})
        for ref, seed in refs:
            scene = resolve_scene(ref, seed, scenes_root=scenes_root)
            out.append((episodes.task, ref, [o.name for o in scene.objects]))
    return out


@dataclass(frozen=True)
class ScoredPair:
    """One query against one segment label of a scene."""

    scene: str
    query: str
    label: str
    score: float
    """``cos(embed(query), embed(label))``."""
    present: bool
    """The label is the queried object's own (else another object's: a near-miss)."""


def score_pairs(scenes: list[tuple[str, str, list[str]]], encoder) -> list[ScoredPair]:
    """Every present and near-miss pair of ``scenes`` (see the module docstring), scored with
    ``encoder`` (``encode_text``: texts -> (n, d) unit rows). Each distinct text is embedded once,
    alone (as the mapper embeds a query).

    Raises:
        ValueError: a scene with two objects of the same label (no query could tell them apart).
    """
    texts = sorted({t for task, _, labels in scenes for n in labels for t in (n, *query_wordings(task, n))})
    vec = {t: np.asarray(encoder.encode_text([t])[0], np.float64) for t in texts}
    pairs = []
    for task, ref, labels in scenes:
        if len(set(labels)) != len(labels):
            raise ValueError(f"scene {ref}: expected distinct object labels, got {labels}")
        for name in labels:
            for q in query_wordings(task, name):
                for other in labels:
                    pairs.append(ScoredPair(ref, q, other, float(vec[q] @ vec[other]), other == name))
    return pairs


@dataclass(frozen=True)
class FloorChoice:
    """A floor and how it classifies the pairs it was chosen on (accepted: score >= floor)."""

    floor: float
    separated: bool
    """Every present score is above every near-miss score."""
    low: float
    """Lower end of the chosen interval of thresholds (exclusive): the highest score still rejected."""
    high: float
    """Upper end of the chosen interval (inclusive): the lowest score accepted."""
    present_rejected: int
    near_miss_accepted: int


def choose_oracle_floor(present: Sequence[float], near_miss: Sequence[float]) -> FloorChoice:
    """The floor between ``present`` and ``near_miss`` scores (see the module docstring's rule).

    Shape:
        ``present`` (P,), ``near_miss`` (N,) with P, N >= 1.

    Raises:
        ValueError: an empty or non-finite sequence, or scores on which accepting or rejecting
            everything beats every floor between two observed scores.
    """
    p = np.sort(np.asarray(present, np.float64).ravel())
    n = np.sort(np.asarray(near_miss, np.float64).ravel())
    if p.size == 0 or n.size == 0 or not (np.isfinite(p).all() and np.isfinite(n).all()):
        raise ValueError(f"expected present and near-miss scores, finite and at least one of each, "
                         f"got {p.size} present and {n.size} near-miss")
    if p[0] > n[-1]:
        return FloorChoice(float((p[0] + n[-1]) / 2), True, float(n[-1]), float(p[0]), 0, 0)
    values = np.unique(np.concatenate([p, n]))
    cuts = values[:-1]  # a threshold in (values[i], values[i + 1]] rejects every score <= values[i]
    rejected = np.searchsorted(p, cuts, side="right")
    accepted = n.size - np.searchsorted(n, cuts, side="right")
    errors = rejected + accepted
    best = int(errors.min())
    if min(n.size, p.size) < best:
        raise ValueError(f"no floor between observed scores beats accepting or rejecting every pair "
                         f"({best} misclassified against {n.size} near-miss and {p.size} present)")
    idx = np.flatnonzero(errors == best)
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)  # adjacent best intervals form one
    spans = [(float(values[r[0]]), float(values[r[-1] + 1])) for r in runs]
    low, high = max(spans, key=lambda s: (s[1] - s[0], -s[0]))
    floor = (low + high) / 2
    return FloorChoice(floor, False, low, high, int((p < floor).sum()), int((n >= floor).sum()))


def _extreme(pairs: list[ScoredPair], lowest: bool) -> ScoredPair:
    key = (lambda q: (q.score, q.query, q.label)) if lowest else (lambda q: (-q.score, q.query, q.label))
    return min(pairs, key=key)


def derive(files: Sequence[str] = CALIBRATION_EPISODE_FILES, *, encoder=None, scenes_root: Path = SCENES_ROOT) -> dict:
    """The floor file's content, derived from the scenes of ``files`` (default encoder: a fresh
    :data:`~conceptfusion.perception.oracle_floor.ORACLE_TEXT_ENCODER`)."""
    scenes = calibration_scenes(files, scenes_root)
    pairs = score_pairs(scenes, encoder if encoder is not None else make_encoder(ORACLE_TEXT_ENCODER))
    present = [q for q in pairs if q.present]
    near = [q for q in pairs if not q.present]
    choice = choose_oracle_floor([q.score for q in present], [q.score for q in near])
    lo, hi = _extreme(present, True), _extreme(near, False)
    r = lambda x: round(float(x), _DIGITS)  # noqa: E731
    rule = ("midpoint between the lowest present and the highest near-miss score (they separate)" if choice.separated
            else "midpoint of the widest interval of thresholds misclassifying the fewest pairs (they overlap)")
    return {
        "format": ORACLE_FLOOR_FORMAT, "version": ORACLE_FLOOR_VERSION,
        "floor": r(choice.floor), "encoder": ORACLE_TEXT_ENCODER, "separated": choice.separated, "rule": rule,
        "present": {"pairs": len(present), "distinct_pairs": len({(q.query, q.label) for q in present}),
                    "min": r(lo.score), "min_pair": [lo.query, lo.label], "rejected": choice.present_rejected},
        "near_miss": {"pairs": len(near), "distinct_pairs": len({(q.query, q.label) for q in near}),
                      "max": r(hi.score), "max_pair": [hi.query, hi.label], "accepted": choice.near_miss_accepted},
        "wordings": dict(WORDINGS), "episode_files": list(files), "scenes": [ref for _, ref, _ in scenes],
        "command": ORACLE_FLOOR_COMMAND,
    }


def _differences(a, b, where: str = "") -> list[str]:
    """Where two floor files differ (numbers within :data:`_TOL` count as equal)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}{k}: only in {'the file' if k in a else 'the derivation'}" for k in sorted(set(a) ^ set(b))]
        for k in sorted(set(a) & set(b)):
            out += _differences(a[k], b[k], f"{where}{k}.")
        return out
    if isinstance(a, float) or isinstance(b, float):
        ok = isinstance(a, (int, float)) and isinstance(b, (int, float)) and math.isclose(a, b, rel_tol=0, abs_tol=_TOL)
        return [] if ok else [f"{where.rstrip('.')}: file {a!r}, derived {b!r}"]
    return [] if a == b else [f"{where.rstrip('.')}: file {a!r}, derived {b!r}"]


def write(path: Path = ORACLE_FLOOR_FILE, derived: dict | None = None) -> dict:
    """Derive (unless ``derived`` is given) and write the floor file atomically; returns its content."""
    data = derived if derived is not None else derive()
    atomic_write_text(path, json.dumps(data, indent=1) + "\n")
    return data


def check(path: Path = ORACLE_FLOOR_FILE, derived: dict | None = None) -> list[str]:
    """What differs between the file at ``path`` and a fresh derivation (empty: they agree).

    Raises what :func:`~conceptfusion.perception.oracle_floor.read_oracle_floor_file` raises.
    """
    return _differences(read_oracle_floor_file(path), derived if derived is not None else derive())


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tower_training.oracle_floor", description=__doc__.splitlines()[0])
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--write", action="store_true", help=f"derive the floor and write {ORACLE_FLOOR_FILE.name}")
    what.add_argument("--check", action="store_true", help="derive the floor and compare with the file (exit 1 if they differ)")
    ap.add_argument("--file", type=Path, default=ORACLE_FLOOR_FILE, help="the floor file (default: the shipped one)")
    args = ap.parse_args(argv)
    derived = derive()
    summary = (f"floor {derived['floor']}: present min {derived['present']['min']} ({derived['present']['pairs']} pairs), "
               f"near-miss max {derived['near_miss']['max']} ({derived['near_miss']['pairs']} pairs), "
               f"{len(derived['scenes'])} scenes")
    if args.write:
        write(args.file, derived)
        print(f"wrote {args.file}: {summary}")
        return 0
    try:
        diffs = check(args.file, derived)
    except (MissingFileError, CalibrationFileError) as exc:
        print(exc, file=sys.stderr)
        return 1
    for d in diffs:
        print(d, file=sys.stderr)
    print(f"{args.file} {'differs from' if diffs else 'matches'} the derivation: {summary}")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
