"""The episode dataset format (JSON Lines), its validating loader, its writer and the tabletop
episode generator.

A file starts with a header line, then holds one episode per line::

    {"format": "cf-episodes", "version": 1, "task": "tabletop_rearrange", "generator_seed": 0}
    {"episode_id": "tabletop-v1-0000", "scene": "tabletop/tabletop-0042.json", "scene_seed": 42,
     "instruction": "push the red mug to the right of the line",
     "goals": [{"object_id": "obj3", "side": "right"}], "start_pose": null, "max_steps": 6}

``scene`` is a path relative to the ``scenes/`` folder (ending in ``.json``) or a scene id
(the one file named ``<id>.json`` under ``scenes/``; a ``tabletop-NNNN`` id with no file is
generated from ``scene_seed``). References are exact: glob characters (``*?[]``), absolute paths
and paths that leave ``scenes/`` are refused, as is an id that two files answer to
(:func:`check_scene_ref`). ``goals`` are ``{object_id, side}`` for rearrangement (side ``left`` or
``right``) and ``{object_id}`` for object search; ``start_pose`` is the agent's ``[x, y, yaw]``
for search and ``null`` on a tabletop.

Version 2 adds an optional per-episode ``description_kind``: how the instruction names the goal
(one of :data:`sim_envs.scenes.descriptions.DESCRIPTION_KINDS`: ``name``, ``synonym``,
``attribute``, ``function``, ``parent``), so reports can split by it; and per goal, optional ``description`` (the phrase that names the
object, "the coffee mug") and ``description_kind`` (rearrangement episodes name one or two goals,
each with the same kind as the episode's), and for object search an optional ``explore_steps``
(an exploration budget before the first goal is revealed). A file whose episodes and goals
carry none of these is written as version 1, byte for byte as before, and version 1
files load as before.

Version 3 adds instruction episodes (:mod:`sim_envs.scenes.instruct_episodes`): an optional
per-episode ``instruction_kind`` (:data:`INSTRUCTION_KINDS`) and per goal an optional ``accept``,
the other objects that satisfy the instruction too (stopping near any of them succeeds).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from conceptfusion.errors import MissingFileError, SimError
from conceptfusion.names import did_you_mean
from conceptfusion.io_utils import MAX_EPISODES_BYTES, atomic_write_text, read_text_file
from conceptfusion.strict_json import loads_strict
from sim_envs.envs.rearrange_eval import signed_line_distance
from sim_envs.scenes.descriptions import DESCRIPTION_KINDS
from sim_envs.scenes.format import Scene, load_scene
from sim_envs.scenes.household_format import MAX_MAGNITUDE
from sim_envs.scenes.gen_tabletop import generate_tabletop

__all__ = [
    "EpisodeFormatError", "Goal", "Episode", "EpisodeSet", "FORMAT", "VERSION", "TASKS", "INSTRUCTION_KINDS", "SCENES_ROOT",
    "MAX_LINE_DISTANCE", "check_scene_ref", "start_outside_message", "load_episodes", "save_episodes", "episodes_text", "resolve_scene", "tabletop_goals", "tabletop_instruction",
    "generate_tabletop_episodes",
]

FORMAT = "cf-episodes"
VERSION = 3
TASKS = ("tabletop_rearrange", "object_search")
SIDES = ("left", "right")
SCENES_ROOT = Path(__file__).resolve().parents[2] / "scenes"
"""The shipped ``scenes/`` folder: the default root that scene paths are relative to."""


class EpisodeFormatError(SimError):
    """An episode file or record is malformed; the message names the file and line."""


@dataclass(frozen=True)
class Goal:
    """One instructed object: ``side`` is ``"left"``/``"right"`` for rearrangement, ``None`` for search."""

    object_id: str
    side: str | None = None
    description: str | None = None
    """How the instruction names the object ("the coffee mug"); None: not recorded."""
    description_kind: str | None = None
    """The description's kind (a ``DESCRIPTION_KINDS`` entry); None: not recorded."""
    accept: tuple[str, ...] = ()
    """Object search only: other objects that satisfy this goal as well (an instruction that
    several objects answer, "something to eat"); stopping near any of them reaches the goal.
    ``object_id`` is the one the episode's shortest path and the oracle head for."""

    def to_json(self) -> dict:
        d: dict = {"object_id": self.object_id}
        for key in ("side", "description", "description_kind"):
            if getattr(self, key) is not None:
                d[key] = getattr(self, key)
        if self.accept:
            d["accept"] = list(self.accept)
        return d


@dataclass(frozen=True)
class Episode:
    """One episode record."""

    episode_id: str
    scene: str
    """Scene path relative to ``scenes/`` (``.json``) or a scene id."""
    scene_seed: int
    instruction: str
    goals: tuple[Goal, ...]
    start_pose: tuple[float, float, float] | None = None
    """Agent start ``(x, y, yaw)`` for search tasks; ``None`` on a tabletop."""
    max_steps: int = 6
    description_kind: str | None = None
    """How ``instruction`` names the goal (a :data:`~sim_envs.scenes.descriptions.DESCRIPTION_KINDS`
    entry); None: not recorded (version 1 episodes)."""
    instruction_kind: str | None = None
    """Instruction episodes (version 3): what the instruction names instead of an object, one of
    :data:`INSTRUCTION_KINDS` (``need``, ``room``, ``relation``); None: a plain search."""
    explore_steps: int = 0
    """Object search only ("explore, then fetch"): steps of exploration before the first goal is
    revealed (the observation's ``goal`` is :data:`conceptfusion.tasks.EXPLORE_GOAL` until then);
    part of ``max_steps``. 0: the goal is shown from the start."""

    def to_json(self) -> dict:
        goals = [g.to_json() for g in self.goals]
        return {
            "episode_id": self.episode_id, "scene": self.scene, "scene_seed": self.scene_seed,
            "instruction": self.instruction, "goals": goals,
            "start_pose": list(self.start_pose) if self.start_pose is not None else None, "max_steps": self.max_steps,
            **({"description_kind": self.description_kind} if self.description_kind is not None else {}),
            **({"explore_steps": self.explore_steps} if self.explore_steps else {}),
            **({"instruction_kind": self.instruction_kind} if self.instruction_kind is not None else {}),
        }


@dataclass(frozen=True)
class EpisodeSet:
    """A whole episode file: header fields plus the episodes in file order."""

    task: str
    generator_seed: int | None
    episodes: tuple[Episode, ...]

    def header(self) -> dict:
        version = 3 if any(e.instruction_kind is not None or any(g.accept for g in e.goals) for e in self.episodes) else 2 if any(
            e.description_kind is not None or e.explore_steps
            or any(g.description is not None or g.description_kind is not None for g in e.goals)
            for e in self.episodes
        ) else 1
        return {"format": FORMAT, "version": version, "task": self.task, "generator_seed": self.generator_seed}


# ------------------------------------------------------------------------------------ loading
def resolve_scene(ref: str, scene_seed: int = 0, *, scenes_root: str | os.PathLike | None = None) -> Scene:
    """The scene an episode names, exactly (:func:`check_scene_ref`): a ``.json`` path relative
    to ``scenes_root``, a scene id whose file ``<id>.json`` is the one file of that name under it,
    or a ``tabletop-NNNN`` id with no file, generated from ``scene_seed``.

    Raises :class:`~conceptfusion.errors.SimError` for a reference with glob characters, an
    absolute path or one that leaves the root, or an id that two files answer to, and
    :class:`~conceptfusion.errors.MissingFileError` when no file matches.
    """
    root = Path(scenes_root) if scenes_root is not None else SCENES_ROOT
    return _resolve_scene_cached(str(ref), int(scene_seed), str(root.resolve()))


_GLOB_CHARS = "*?[]"
_SCENE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
_GENERATED_ID = re.compile(r"tabletop-[0-9]+")


def check_scene_ref(ref: str, scenes_root: str | os.PathLike | None = None) -> Path | None:
    """The file a scene reference names, checked: ``None`` for a bare scene id (see
    :func:`resolve_scene`), else the path under ``scenes_root`` (not checked for existence).

    A reference is matched literally: ``"*"`` or ``"household-000[0-9]"`` is not a pattern
    but a mistake, refused with :class:`~conceptfusion.errors.SimError` naming what a
    reference looks like, as are absolute paths, backslashes and paths that climb out of the
    root (``..``, or a symlink that points outside it).
    """
    base = Path(scenes_root) if scenes_root is not None else SCENES_ROOT
    expected = ("expected a path relative to the scenes root ending in .json ('tabletop/tabletop-0042.json') or a "
                "scene id of letters, digits, '.', '_' and '-' ('tabletop-0042')")
    bad = sorted({c for c in ref if c in _GLOB_CHARS})
    if bad:
        raise SimError(f"scene {ref!r}: {expected}; got glob character(s) {' '.join(bad)} (references are exact, not "
                       "patterns)")
    if not ref.endswith(".json"):
        if not _SCENE_ID.fullmatch(ref):
            raise SimError(f"scene {ref!r}: {expected}")
        return None
    if "\\" in ref or "\0" in ref or ref.startswith(("/", "~")) or ".." in Path(ref).parts or Path(ref).is_absolute():
        raise SimError(f"scene {ref!r}: {expected}; got an absolute path, a backslash or '..'")
    path = base / ref
    root = base.resolve()
    if not path.resolve().is_relative_to(root):
        raise SimError(f"scene {ref!r}: {expected}; the path leads to {path.resolve()}, outside the scenes root {root}")
    return path


@lru_cache(maxsize=256)
def _resolve_scene_cached(ref: str, scene_seed: int, root: str) -> Scene:
    base = Path(root)
    path = check_scene_ref(ref, base)
    if path is not None:
        if not path.exists():
            raise MissingFileError(f"scene file {path} does not exist (scene {ref!r}, relative to {base})")
        return load_scene(path)
    name = f"{ref}.json"
    found = sorted(Path(folder) / name for folder, _, files in os.walk(base) if name in files) if base.is_dir() else []
    if len(found) > 1:
        listed = ", ".join(str(f.relative_to(base)) for f in found)
        raise SimError(f"scene {ref!r}: {len(found)} files are named {name} under {base} ({listed}); expected one: name the "
                       "file by its path relative to the scenes root")
    if found:
        if not found[0].resolve().is_relative_to(base):
            raise SimError(f"scene {ref!r}: {found[0]} leads to {found[0].resolve()}, outside the scenes root {base}")
        return load_scene(found[0])
    if _GENERATED_ID.fullmatch(ref):
        return generate_tabletop(scene_seed)
    raise MissingFileError(f"scene {ref!r}: no file {ref}.json under {base}, and only tabletop-NNNN ids can be generated")


_EPISODE_FIELDS = ("episode_id", "scene", "scene_seed", "instruction", "goals", "start_pose", "max_steps", "description_kind",
                   "explore_steps", "instruction_kind")
INSTRUCTION_KINDS = ("need", "room", "relation")
"""What an instruction episode's instruction names: a need ("something to eat"), a need or group in
a room ("something to write with in the study"), or an object by its relation to another ("something
on the dining table")."""
_HEADER_FIELDS = ("format", "version", "task", "generator_seed")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _field(d: dict, key: str, kind, where: str):
    if key not in d:
        raise EpisodeFormatError(f"{where}: missing field {key!r}")
    v = d[key]
    if kind is int and not _is_int(v):
        raise EpisodeFormatError(f"{where}: {key!r} expected an integer, got {v!r}")
    if kind is str and (not isinstance(v, str) or not v.strip()):
        raise EpisodeFormatError(f"{where}: {key!r} expected a non-empty string, got {v!r}")
    return v


def _check_keys(d: dict, allowed: tuple[str, ...], where: str) -> None:
    for k in d:
        if k not in allowed:
            raise EpisodeFormatError(f"{where}: unknown field {k!r}{did_you_mean(k, allowed)} (fields: {', '.join(allowed)})")


def _parse_episode(d, task: str, where: str) -> Episode:
    if not isinstance(d, dict):
        raise EpisodeFormatError(f"{where}: expected a JSON object, got {type(d).__name__}")
    _check_keys(d, _EPISODE_FIELDS, where)
    goals_raw = _field(d, "goals", list, where)
    if not isinstance(goals_raw, list) or not goals_raw:
        raise EpisodeFormatError(f"{where}: 'goals' expected a non-empty list, got {goals_raw!r}")
    goals, ids = [], []
    for k, g in enumerate(goals_raw):
        if not isinstance(g, dict) or not isinstance(g.get("object_id"), str) or not g["object_id"]:
            raise EpisodeFormatError(f"{where}: goals[{k}] expected {{'object_id': str, ...}}, got {g!r}")
        _check_keys(g, ("object_id", "side", "description", "description_kind", "accept"), f"{where}: goals[{k}]")
        accept = g.get("accept", [])
        if not isinstance(accept, list) or not all(isinstance(a, str) and a for a in accept) or g["object_id"] in accept \
                or len(set(accept)) != len(accept):
            raise EpisodeFormatError(f"{where}: goals[{k}].accept expected a list of distinct object ids other than "
                                     f"{g['object_id']!r}, got {accept!r}")
        if accept and task != "object_search":
            raise EpisodeFormatError(f"{where}: goals[{k}].accept is for object_search episodes, got it in a {task!r} file")
        desc, desc_kind = g.get("description"), g.get("description_kind")
        if desc is not None and (not isinstance(desc, str) or not desc.strip()):
            raise EpisodeFormatError(f"{where}: goals[{k}].description expected a non-empty string, got {desc!r}")
        if desc_kind is not None and desc_kind not in DESCRIPTION_KINDS:
            raise EpisodeFormatError(f"{where}: goals[{k}].description_kind expected null or one of {DESCRIPTION_KINDS}, got {desc_kind!r}")
        side = g.get("side")
        if task == "tabletop_rearrange" and side not in SIDES:
            raise EpisodeFormatError(f"{where}: goals[{k}].side expected one of {SIDES}, got {side!r}")
        if task != "tabletop_rearrange" and side is not None:
            raise EpisodeFormatError(f"{where}: goals[{k}].side expected no side for task {task!r}, got {side!r}")
        if g["object_id"] in ids:
            raise EpisodeFormatError(f"{where}: goals[{k}].object_id {g['object_id']!r} repeats goals[{ids.index(g['object_id'])}]")
        ids.append(g["object_id"])
        goals.append(Goal(g["object_id"], side, desc, desc_kind, tuple(accept)))
    pose = d.get("start_pose")
    if pose is not None:
        if not isinstance(pose, list) or len(pose) != 3 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in pose
        ):
            raise EpisodeFormatError(f"{where}: 'start_pose' expected null or [x, y, yaw] (3 finite numbers), got {pose!r}")
        if any(abs(v) > MAX_MAGNITUDE for v in pose):
            raise EpisodeFormatError(f"{where}: 'start_pose' expected [x, y, yaw] within +-{MAX_MAGNITUDE:g} (metres, "
                                     f"radians), got {pose!r}")
        pose = tuple(float(v) for v in pose)
    max_steps = _field(d, "max_steps", int, where)
    if max_steps < 1:
        raise EpisodeFormatError(f"{where}: 'max_steps' expected >= 1, got {max_steps}")
    scene_seed = _field(d, "scene_seed", int, where)
    if scene_seed < 0:
        raise EpisodeFormatError(f"{where}: 'scene_seed' expected >= 0, got {scene_seed}")
    kind = d.get("description_kind")
    if kind is not None and kind not in DESCRIPTION_KINDS:
        raise EpisodeFormatError(f"{where}: 'description_kind' expected null or one of {DESCRIPTION_KINDS}, got {kind!r}")
    instruction_kind = d.get("instruction_kind")
    if instruction_kind is not None and instruction_kind not in INSTRUCTION_KINDS:
        raise EpisodeFormatError(f"{where}: 'instruction_kind' expected null or one of {INSTRUCTION_KINDS}, got {instruction_kind!r}")
    explore = d.get("explore_steps", 0)
    if not _is_int(explore) or not 0 <= explore < max_steps:
        raise EpisodeFormatError(f"{where}: 'explore_steps' expected an integer in [0, max_steps) = [0, {max_steps}), got {explore!r}")
    if explore and task != "object_search":
        raise EpisodeFormatError(f"{where}: 'explore_steps' is for object_search episodes, got it in a {task!r} file")
    return Episode(
        episode_id=_field(d, "episode_id", str, where), scene=_field(d, "scene", str, where),
        scene_seed=scene_seed, instruction=_field(d, "instruction", str, where),
        goals=tuple(goals), start_pose=pose, max_steps=max_steps, description_kind=kind, explore_steps=explore,
        instruction_kind=instruction_kind,
    )


def _read_lines(p: Path) -> list[str]:
    return read_text_file(p, "episode file", EpisodeFormatError, max_bytes=MAX_EPISODES_BYTES).splitlines()


def _parse_header(header, where: str) -> tuple[str, int | None]:
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else header
        raise EpisodeFormatError(f"{where}: expected a header with format {FORMAT!r}, got {got!r}")
    version = header.get("version")
    if not _is_int(version) or version < 1 or version > VERSION:
        raise EpisodeFormatError(f"{where}: expected version <= {VERSION} (an integer >= 1), got {version!r}")
    _check_keys(header, _HEADER_FIELDS, f"{where}: header")
    task = header.get("task")
    if task not in TASKS:
        raise EpisodeFormatError(f"{where}: expected task in {TASKS}, got {task!r}")
    seed = header.get("generator_seed")
    if seed is not None and not _is_int(seed):
        raise EpisodeFormatError(f"{where}: 'generator_seed' expected an integer or null, got {seed!r}")
    return task, seed


def load_episodes(
    path: str | os.PathLike, *, scenes_root: str | os.PathLike | None = None, check_scenes: bool = True
) -> EpisodeSet:
    """Read and validate an episode file.

    Raises :class:`EpisodeFormatError` naming the file, the 1-based line number and the field
    for a path that is not a regular file or is larger than
    :data:`~conceptfusion.io_utils.MAX_EPISODES_BYTES`, a file that is not UTF-8 text, a line
    that is not JSON (NaN and infinities included; a key twice in one object, nesting deeper
    than :data:`~conceptfusion.strict_json.MAX_JSON_DEPTH` or an integer of more than
    :data:`~conceptfusion.strict_json.MAX_INT_DIGITS` digits) or not a valid record (a missing or
    unknown field, a value of the wrong type or range, a start pose beyond
    :data:`~sim_envs.scenes.household_format.MAX_MAGNITUDE`), a bad header, or a duplicate
    episode id; with ``check_scenes`` every scene is resolved (:func:`resolve_scene`, exact
    references only; a missing or invalid scene is an :class:`EpisodeFormatError` naming the
    line), every goal object id must exist in it and a start pose must lie within the
    apartment's bounds (:func:`start_outside_message`). A missing file raises
    :class:`~conceptfusion.errors.MissingFileError`.
    """
    p = Path(path)
    records = []
    for no, line in enumerate(_read_lines(p), start=1):
        if not line.strip():
            continue
        try:
            records.append((no, loads_strict(line, source=str(p), line=no, error=EpisodeFormatError, allow_nan=False)))
        except json.JSONDecodeError as exc:
            raise EpisodeFormatError(f"{p}:line {no}: not valid JSON ({exc.msg} at column {exc.colno})") from exc
    if not records:
        raise EpisodeFormatError(f"{p}: expected a header line, got an empty file")
    no, header = records[0]
    task, seed = _parse_header(header, f"{p}:line {no}")
    episodes, seen = [], set()
    for no, rec in records[1:]:
        where = f"{p}:line {no}"
        ep = _parse_episode(rec, task, where)
        if ep.episode_id in seen:
            raise EpisodeFormatError(f"{where}: duplicate episode_id {ep.episode_id!r}")
        seen.add(ep.episode_id)
        if check_scenes:
            try:
                scene = resolve_scene(ep.scene, ep.scene_seed, scenes_root=scenes_root)
            except (OSError, ValueError) as exc:
                raise EpisodeFormatError(f"{where}: episode {ep.episode_id!r}: field 'scene': {exc}") from exc
            _check_start_inside(ep, scene, where)
            ids = [o.id for o in scene.objects]
            for g in ep.goals:
                if g.object_id not in ids:
                    raise EpisodeFormatError(
                        f"{where}: episode {ep.episode_id!r} names object {g.object_id!r}, which scene {scene.id!r} lacks (objects: {ids})"
                    )
        episodes.append(ep)
    return EpisodeSet(task, seed, tuple(episodes))


def start_outside_message(scene: Scene, xy) -> str | None:
    """Why start position ``xy`` cannot be in household ``scene``: outside the bounding box of
    its rooms' floors (the apartment's bounds, named in the message); None when it is inside
    them or the scene has no rooms."""
    bounds = scene.floor_bounds()
    if bounds is None:
        return None
    (x0, y0), (x1, y1) = bounds
    x, y = float(xy[0]), float(xy[1])
    if x0 <= x <= x1 and y0 <= y <= y1:
        return None
    return (f"start pose ({x:.2f}, {y:.2f}) is outside the apartment's bounds x in [{x0:.2f}, {x1:.2f}], "
            f"y in [{y0:.2f}, {y1:.2f}] (scene {scene.id!r})")


def _check_start_inside(ep: Episode, scene: Scene, where: str) -> None:
    if ep.start_pose is None:
        return
    why = start_outside_message(scene, ep.start_pose[:2])
    if why:
        raise EpisodeFormatError(f"{where}: episode {ep.episode_id!r}: field 'start_pose': {why}")


def episodes_text(episodes: EpisodeSet) -> str:
    """The JSON Lines text of an episode set (header first, one episode per line)."""
    lines = [json.dumps(episodes.header())] + [json.dumps(e.to_json()) for e in episodes.episodes]
    return "\n".join(lines) + "\n"


def save_episodes(episodes: EpisodeSet, path: str | os.PathLike) -> Path:
    """Write an episode file atomically."""
    if episodes.task not in TASKS:
        raise ValueError(f"task: expected one of {TASKS}, got {episodes.task!r}")
    return atomic_write_text(path, episodes_text(episodes))


# ------------------------------------------------------------------------------------ tabletop
def _side_of(scene: Scene, index: int) -> str:
    """Which side of the line (``left``/``right``) object ``index`` stands on."""
    d = signed_line_distance(scene, np.asarray(scene.objects[index].position[:2])[None, :])[0]
    return "right" if d > 0 else "left"


MAX_LINE_DISTANCE = 0.25
"""Targets are drawn among objects whose centre lies within this distance (m) of the line, as in
the paper's set-up (short pushes across a line), so that a few pushes can solve an episode."""


def tabletop_goals(
    scene: Scene, rng: np.random.Generator, *, num_targets: tuple[int, int] = (1, 2), max_line_distance: float = MAX_LINE_DISTANCE
) -> tuple[Goal, ...]:
    """1-2 distinct target objects within ``max_line_distance`` of the line, each instructed to the
    side of the line it is not on. Empty when no object is that close."""
    centres = np.array([o.position[:2] for o in scene.objects], float).reshape(-1, 2)
    eligible = np.flatnonzero(np.abs(signed_line_distance(scene, centres)) <= max_line_distance)
    n = min(len(eligible), int(rng.integers(num_targets[0], num_targets[1] + 1)))
    if n == 0:
        return ()
    picks = rng.choice(eligible, size=n, replace=False)
    return tuple(Goal(scene.objects[i].id, "left" if _side_of(scene, int(i)) == "right" else "right") for i in sorted(picks))


def tabletop_instruction(scene: Scene, goals: tuple[Goal, ...]) -> str:
    """``"push the red mug to the right of the line"`` (targets joined with ``and``)."""
    parts = [f"the {scene.object(g.object_id).name} to the {g.side} of the line" for g in goals]
    return "push " + " and ".join(parts)


def generate_tabletop_episodes(
    generator_seed: int, count: int, *, max_steps: int = 6, scene_dir: str = "tabletop"
) -> tuple[EpisodeSet, list[Scene]]:
    """``count`` tabletop rearrangement episodes, one generated scene each.

    Scene seeds are distinct draws from ``np.random.default_rng(generator_seed)`` (a scene with no
    object near the line is skipped); each episode's
    scene is referred to as ``<scene_dir>/<scene id>.json``. Returns the episode set and the
    scenes (for writing the scene files).
    """
    if count < 1:
        raise ValueError(f"count: expected >= 1, got {count}")
    rng = np.random.default_rng(generator_seed)
    seeds = rng.permutation(10_000)
    episodes, scenes = [], []
    for s in seeds:
        if len(episodes) == count:
            break
        scene = generate_tabletop(int(s))
        goals = tabletop_goals(scene, rng)
        if not goals:
            continue
        k = len(episodes)
        episodes.append(
            Episode(
                episode_id=f"tabletop-v1-{k:04d}", scene=f"{scene_dir}/{scene.id}.json", scene_seed=int(s),
                instruction=tabletop_instruction(scene, goals), goals=goals, start_pose=None, max_steps=max_steps,
            )
        )
        scenes.append(scene)
    return EpisodeSet("tabletop_rearrange", int(generator_seed), tuple(episodes)), scenes
