"""Episode recordings: what an agent saw, did and was told by its map, step by step.

An :class:`EpisodeRecorder` follows one episode. The rollout calls :meth:`~EpisodeRecorder.begin`
after the reset, :meth:`~EpisodeRecorder.act` once the agent has chosen an action and
:meth:`~EpisodeRecorder.step` after the environment stepped; it only reads what it is given and
never changes the episode. It buffers in memory, and :meth:`~EpisodeRecorder.finish` writes the
recording (see :data:`RECORD_MODES`: every episode, or the failures and one success per suite and
agent) to ``RUN/replays/<stem>.npz`` (:func:`harness.report.paths.replay_stem`), and a map agent's
final map beside it as ``<stem>.map.npz`` (:func:`conceptfusion.map.persistence.save_map`) when
that map is under :data:`MAP_BUDGET_BYTES`.

A recording file is a compressed ``.npz`` holding a JSON ``header`` (format, version, the
episode's key fields, goal text and ``goal_changes`` (``[frame, text]`` each time a chain reveals
its next goal), scene, what success needs (search: ``success_distance`` m; rearrange:
``side_margin`` and ``distractor_tolerance`` m), outcome (``status``, ``success``, ``metrics``,
``error``, ``stop_reason`` when the harness passed one, ``recorded_as``), the queries the map
answered, the map file) and these arrays, for an episode of ``T`` steps (``T + 1`` frames: the
reset's and one per step):

=====================  ===================  ===========================================================
``frames_jpeg``        (B,) uint8           the camera frames, JPEG, one after the other
``frame_offsets``      (T + 2,) int64       frame ``i`` is ``frames_jpeg[off[i]:off[i + 1]]``
``actions_ta``         (T, A) float32       the action chosen on frame ``t``
``reward_t``           (T + 1,) float32     reward received on reaching frame ``t`` (0 at the reset)
``success_t``          (T + 1,) bool        the environment's success flag on frame ``t``
``answer_found_tq``    (T + 1, Q) int8      the map's answer to query ``q`` on frame ``t``: 1 found,
                                            0 not found, -1 not asked yet
``answer_median_tq3``  (T + 1, Q, 3) f32    the best region's median (world metres; NaN: none)
``answer_box_tq23``    (T + 1, Q, 2, 3) f32 the best region's box, lower and upper corner
``pose_t3``            (T + 1, 3) float64   search: base pose ``(x, y, yaw)`` per frame
``goal_distance_t``    (T + 1,) float32     search: the base's distance to the current goal's box (m)
``goal_box_23``        (2, 3) float64       search: the (first) goal object's box
``goal_box_t23``       (T + 1, 2, 3) f64    search: the current goal object's box per frame
``floor_blocked_hw``   (H, W) bool          search: the floor plan (header ``floor``: origin, cell)
``objects_tn2``        (T + 1, N, 2) f32    rearrange: every object's xy per frame
``target_past_line_tk``(T + 1, K) float32   rearrange: each target's distance past the line on its side (m)
``distractor_shift_t`` (T + 1,) float32     rearrange: the largest move of another object from its start (m)
``object_radius_n``    (N,) float32         rearrange: half the larger side of each object's footprint
``table_xy_22``        (2, 2) float64       rearrange: table top lower and upper corner
``line_22``            (2, 2) float64       rearrange: the line's two endpoints
=====================  ===================  ===========================================================

:func:`load_recording` reads one back, with :class:`~conceptfusion.errors.ReplayFormatError`
naming the file and the problem for anything that is not a whole recording.
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import re
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import cv2
import numpy as np

from conceptfusion.array_files import check_npz_headers
from conceptfusion.errors import HarnessError, MissingFileError, ReplayFormatError
from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import save_map
from conceptfusion.map.thin import thin_map
from conceptfusion.names import did_you_mean
from harness.report.paths import MAP_SUFFIX
from sim_envs.envs.rearrange_eval import DISTRACTOR_TOLERANCE, SIDE_MARGIN
from sim_envs.scenes.floorplan import occupancy_grid

__all__ = [
    "RECORD_MODES", "FORMAT_NAME", "FORMAT_VERSION", "MAP_BUDGET_BYTES", "Recording", "EpisodeRecorder",
    "check_record_mode", "save_recording", "load_recording", "read_header", "is_recording_file", "success_marker",
    "OUTCOME_EXTRAS",
]

_LOG = logging.getLogger(__name__)

RECORD_MODES = ("failures", "all", "none")
"""``--record``: ``"failures"`` (the default) writes every episode that failed and, to compare
them with, the first successful episode of each suite and agent (label) that has none recorded
yet; ``"all"`` every episode; ``"none"`` nothing. Which success was kept is noted in the replays
folder (:func:`success_marker`), so a resumed run or several workers keep one (two workers that
finish a first success at the same moment may keep two)."""
FORMAT_NAME = "cfharness-replay"
FORMAT_VERSION = 1
MAP_BUDGET_BYTES = 16 * 2**20
"""A map agent's final map is saved beside its recording (:func:`~conceptfusion.map.persistence.save_map`,
uncompressed: deflating it would cost more than the 10% of an episode a recording may take) within
this many bytes (:meth:`~conceptfusion.map.fusion.PointFusionMap.nbytes`): a tabletop map of a scan
(about 8 MB) is saved whole; an apartment map of a whole search episode (about 50 MB) is thinned
to one point per voxel (:func:`~conceptfusion.map.thin.thin_map`; each kept point exact), and the
recording's header says so. The recording keeps the map's answers either way."""

OUTCOME_EXTRAS = ("goal", "stop_reason", "success_radius", "planner")
"""Keys of a results record's ``extras`` that :meth:`EpisodeRecorder.finish` copies into the header
(``planner``: an instruction agent's planner calls, shown on the frames from the step of each)."""

_FRAME_WIDTH = 160
_JPEG_QUALITY = 75
_NO_ANSWER = -1


def check_record_mode(value: Any, flag: str = "--record") -> str:
    """``value`` if it is one of :data:`RECORD_MODES`, else a
    :class:`~conceptfusion.errors.HarnessError` naming ``flag``, the modes and the nearest one."""
    if not isinstance(value, str) or value not in RECORD_MODES:
        raise HarnessError(f"{flag}: expected one of {', '.join(RECORD_MODES)}, got {value!r}"
                           + (did_you_mean(value, RECORD_MODES, n=1, cutoff=0.5) if isinstance(value, str) else ""))
    return value


def is_recording_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is named like a recording (``*.npz`` but not a final map ``*.map.npz``)."""
    name = Path(path).name
    return name.endswith(".npz") and not name.endswith(MAP_SUFFIX)


# -- the recording ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Recording:
    """One recorded episode: ``header`` (JSON-able metadata) and ``arrays`` (see the module
    docstring for names and shapes)."""

    header: dict
    arrays: dict[str, np.ndarray]

    @property
    def task(self) -> str:
        return str(self.header.get("task", ""))

    @property
    def num_frames(self) -> int:
        """``T + 1``: the reset's frame and one per step."""
        return int(len(self.arrays["frame_offsets"]) - 1)

    @property
    def queries(self) -> list[str]:
        """The descriptions the map was asked for, in the order of the answer arrays' ``q`` axis."""
        return list(self.header.get("queries", []))

    def jpeg(self, i: int) -> bytes:
        """The JPEG bytes of frame ``i`` (0 <= i < :attr:`num_frames`)."""
        if not 0 <= i < self.num_frames:
            raise IndexError(f"frame: expected an index in [0, {self.num_frames}), got {i}")
        off = self.arrays["frame_offsets"]
        return self.arrays["frames_jpeg"][int(off[i]):int(off[i + 1])].tobytes()

    def frame_rgb(self, i: int) -> np.ndarray:
        """Frame ``i`` decoded, (H, W, 3) uint8 RGB."""
        bgr = cv2.imdecode(np.frombuffer(self.jpeg(i), np.uint8), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ReplayFormatError(f"recording of {self.header.get('episode_id')!r}: frame {i} is not a readable JPEG")
        return np.ascontiguousarray(bgr[:, :, ::-1])


def save_recording(recording: Recording, path: str | os.PathLike) -> Path:
    """Write ``recording`` to ``path`` (compressed ``.npz``) atomically; returns the path."""
    header = {"format": FORMAT_NAME, "version": FORMAT_VERSION, **recording.header}
    buf = io.BytesIO()
    np.savez_compressed(buf, header=np.frombuffer(json.dumps(header).encode("utf-8"), np.uint8), **recording.arrays)
    return atomic_write_bytes(path, buf.getvalue())


_REQUIRED = {  # name: (dtype kinds, ndim)
    "frames_jpeg": ("u", 1), "frame_offsets": ("i", 1), "actions_ta": ("f", 2), "reward_t": ("f", 1), "success_t": ("b", 1),
    "answer_found_tq": ("i", 2), "answer_median_tq3": ("f", 3), "answer_box_tq23": ("f", 4),
}
_OPTIONAL = {
    "pose_t3": ("f", 2), "goal_box_23": ("f", 2), "floor_blocked_hw": ("b", 2), "objects_tn2": ("f", 3),
    "object_radius_n": ("f", 1), "table_xy_22": ("f", 2), "line_22": ("f", 2),
    "goal_distance_t": ("f", 1), "goal_box_t23": ("f", 3), "target_past_line_tk": ("f", 2), "distractor_shift_t": ("f", 1),
}
_PER_FRAME = ("reward_t", "success_t", "answer_found_tq", "answer_median_tq3", "answer_box_tq23", "pose_t3", "objects_tn2",
              "goal_distance_t", "goal_box_t23", "target_past_line_tk", "distractor_shift_t")
_HEADER_KEYS = ("task", "suite", "agent", "episode_id", "seed")


def _open(path: str | os.PathLike) -> tuple[Path, Any]:
    p = Path(path)
    if not p.is_file():
        if p.exists():
            raise ReplayFormatError(f"{p}: expected an episode recording (.npz), got a {'folder' if p.is_dir() else 'special file'}")
        raise MissingFileError(f"recording not found: {p}")
    with open(p, "rb") as f:
        head = f.read(4)
    if head != b"PK\x03\x04":
        raise ReplayFormatError(f"{p}: not an episode recording: expected an .npz archive (zip), the file starts with {head!r}")
    try:
        check_npz_headers(p, ReplayFormatError, what="episode recording")  # before np.load allocates
        return p, np.load(p, allow_pickle=False)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ReplayFormatError(f"{p}: not a readable episode recording (truncated or corrupt archive: {exc})") from None


def _header(p: Path, npz) -> dict:
    if "header" not in npz.files:
        raise ReplayFormatError(f"{p}: not an episode recording: no 'header' entry (entries: {', '.join(npz.files) or 'none'})")
    try:
        header = json.loads(npz["header"].tobytes().decode("utf-8"))
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ReplayFormatError(f"{p}: the recording's header is unreadable (truncated or corrupt: {exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise ReplayFormatError(f"{p}: not an episode recording: expected format {FORMAT_NAME!r}, got {got!r}")
    version = header.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ReplayFormatError(f"{p}: recording header: expected an integer version >= 1, got {version!r}")
    if version > FORMAT_VERSION:
        raise ReplayFormatError(f"{p}: recording format version {version} is newer than this harness reads ({FORMAT_VERSION}); "
                                "upgrade the harness")
    missing = [k for k in _HEADER_KEYS if k not in header]
    if missing:
        raise ReplayFormatError(f"{p}: recording header lacks {', '.join(missing)}")
    return header


def read_header(path: str | os.PathLike) -> dict:
    """The header of the recording at ``path`` without reading its frames (errors as
    :func:`load_recording`)."""
    p, npz = _open(path)
    with npz:
        return _header(p, npz)


def load_recording(path: str | os.PathLike) -> Recording:
    """Read a recording written by :func:`save_recording` (or an :class:`EpisodeRecorder`).

    Raises:
        MissingFileError: (a ``FileNotFoundError``) no such file.
        ReplayFormatError: (a ``ValueError``) naming the file and the problem: not an ``.npz``
            archive, truncated or corrupt, another format, a newer version, a header field or an
            array missing, arrays of the wrong dtype or of lengths that disagree.
    """
    p, npz = _open(path)
    with npz:
        header = _header(p, npz)
        arrays = {}
        for name in npz.files:
            if name == "header":
                continue
            try:
                arrays[name] = npz[name]
            except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
                raise ReplayFormatError(f"{p}: array {name!r} of the recording is unreadable (truncated or corrupt: {exc})") from None
    missing = [k for k in _REQUIRED if k not in arrays]
    if missing:
        raise ReplayFormatError(f"{p}: the recording lacks arrays {', '.join(missing)}")
    for name, (kinds, ndim) in {**_REQUIRED, **_OPTIONAL}.items():
        a = arrays.get(name)
        if a is not None and (a.dtype.kind not in kinds or a.ndim != ndim):
            raise ReplayFormatError(f"{p}: array {name!r}: expected {ndim}-D of kind {kinds!r}, got {a.ndim}-D {a.dtype}")
    off, data = arrays["frame_offsets"], arrays["frames_jpeg"]
    if len(off) < 2 or off[0] != 0 or np.any(np.diff(off) <= 0) or off[-1] != len(data):
        raise ReplayFormatError(f"{p}: frame_offsets: expected increasing offsets from 0 to {len(data)} (the JPEG bytes), "
                                f"got {len(off)} offsets ending at {int(off[-1]) if len(off) else None}")
    frames = len(off) - 1
    for name in _PER_FRAME:
        if name in arrays and len(arrays[name]) != frames:
            raise ReplayFormatError(f"{p}: array {name!r}: expected one row per frame ({frames}), got {len(arrays[name])}")
    if len(arrays["actions_ta"]) != frames - 1:
        raise ReplayFormatError(f"{p}: array 'actions_ta': expected one row per step ({frames - 1}), got {len(arrays['actions_ta'])}")
    if arrays["answer_found_tq"].shape[1] != len(header.get("queries", [])):
        raise ReplayFormatError(f"{p}: answers for {arrays['answer_found_tq'].shape[1]} queries, header names "
                                f"{len(header.get('queries', []))}")
    return Recording(header, arrays)


# -- what each task records -------------------------------------------------------------------

_FLOOR_CACHE: dict[str, Any] = {}


def _floor_plan(scene) -> Any:
    """The scene's floor plan (:func:`~sim_envs.scenes.floorplan.occupancy_grid`), cached per scene id."""
    grid = _FLOOR_CACHE.get(scene.id)
    if grid is None:
        if len(_FLOOR_CACHE) > 32:
            _FLOOR_CACHE.clear()
        grid = _FLOOR_CACHE[scene.id] = occupancy_grid(scene, cell=0.05)
    return grid


def _search_scene(env, obs, info) -> tuple[dict, dict]:
    u = env.unwrapped
    grid = _floor_plan(u.scene)
    header = {"goal": str(obs["goal"]), "scene_id": u.scene.id,
              "floor": {"origin": [float(v) for v in grid.origin], "cell": float(grid.cell)},
              "success_distance": float(info.get("success_distance", 1.0))}
    return header, {"goal_box_23": np.asarray(u.goal_box, np.float64).copy(), "floor_blocked_hw": grid.blocked_hw.copy()}


def _search_state(obs, info) -> dict:
    """The pose, the distance to the current goal and (at the reset and when a chain reveals its
    next goal: the frames whose ``info`` has it) the current goal's box; a frame without a key
    keeps the previous frame's value (:meth:`EpisodeRecorder.recording`)."""
    state = {"pose_t3": np.asarray(obs["base_pose"], np.float64)[:3].copy(),
             "goal_distance_t": np.float32(info.get("distance_to_goal", np.nan))}
    if info.get("goal_aabb") is not None:
        state["goal_box_t23"] = np.asarray(info["goal_aabb"], np.float64).reshape(2, 3).copy()
    return state


def _rearrange_scene(env, obs, info) -> tuple[dict, dict]:
    ids = list(info["object_ids"])
    sizes = np.asarray(info["object_sizes"], np.float64).reshape(len(ids), -1)
    header = {"goal": str(obs["instruction"]), "scene_id": str(info.get("scene_id", "")),
              "objects": {"ids": ids, "names": list(info["object_names"]),
                          "targets": [ids.index(t) for t in info["target_ids"] if t in ids],
                          "sides": list(info["target_sides"])},
              "side_margin": SIDE_MARGIN, "distractor_tolerance": DISTRACTOR_TOLERANCE}
    return header, {
        "table_xy_22": np.asarray(info["table_xy"], np.float64).reshape(2, 2).copy(),
        "line_22": np.asarray(obs["line"], np.float64).reshape(2, 2).copy(),
        "object_radius_n": (np.max(sizes[:, :2], axis=1) / 2 if len(ids) else np.zeros(0)).astype(np.float32),
    }


def _rearrange_state(obs, info) -> dict:
    """Every object's xy and, from the environment's judgement, how far each target is past the
    line on its side and how far the other objects moved."""
    poses = np.asarray(info["object_poses"], np.float64)
    ev = info.get("evaluation") or {}
    past = np.asarray(ev.get("target_past_line", [np.nan] * len(info.get("target_ids", []))), np.float32).ravel()
    return {"objects_tn2": poses.reshape(len(poses), -1)[:, :2].astype(np.float32), "target_past_line_tk": past,
            "distractor_shift_t": np.float32(ev.get("max_distractor_displacement", np.nan))}


_TASK_PROBES: dict[str, tuple[Callable, Callable]] = {
    "object_search": (_search_scene, _search_state),
    "tabletop_rearrange": (_rearrange_scene, _rearrange_state),
}
"""Task -> (scene probe ``(env, obs, info) -> (header, arrays)`` at the reset, state probe
``(obs, info) -> per-frame arrays``). Other tasks record frames, actions and answers only."""


# -- the recorder ----------------------------------------------------------------------------

class EpisodeRecorder:
    """Buffers one episode in memory and writes it when :meth:`finish` says so.

    Args:
        task: the episode's task (``"object_search"``, ``"tabletop_rearrange"``; others record
            frames, actions and answers only).
        header: metadata stored as given (the episode's key fields, ``run_id``, ``scene``, ...);
            must hold ``suite, agent, episode_id, seed``.
        path: the recording file to write (``RUN/replays/<stem>.npz``).
        mode: one of :data:`RECORD_MODES`.
        agent: the agent, read only: its mapper's answers (``agent.mapper.answers``) and final
            map (``agent.mapper.map``) when it has them.

    A problem inside the recorder (an observation it cannot read) never stops the episode: the
    recorder logs it and records nothing more. :attr:`seconds` is the time it spent.
    """

    def __init__(self, task: str, header: Mapping, path: str | os.PathLike, *, mode: str = "failures", agent: Any = None,
                 frame_width: int = _FRAME_WIDTH, jpeg_quality: int = _JPEG_QUALITY) -> None:
        self.mode = check_record_mode(mode, "record")
        missing = [k for k in ("suite", "agent", "episode_id", "seed") if k not in header]
        if missing:
            raise HarnessError(f"EpisodeRecorder: header lacks {', '.join(missing)}")
        self.task, self.header, self.path = str(task), dict(header), Path(path)
        self.frame_width, self.jpeg_quality = int(frame_width), int(jpeg_quality)
        self.agent = agent
        self._mapper = getattr(agent, "mapper", None)
        self._has_answers = isinstance(getattr(self._mapper, "answers", None), Mapping)
        self._scene_probe, self._state_probe = _TASK_PROBES.get(self.task, (None, None))
        self.seconds = 0.0
        self.broken: str | None = None
        self.written: list[Path] = []
        self._jpegs: list[bytes] = []
        self._states: list[dict] = []
        self._actions: list[np.ndarray] = []
        self._rewards: list[float] = []
        self._success: list[bool] = []
        self._queries: list[str] = []
        self._seen: dict[str, Any] = {}
        self._current: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}
        self._answer_rows: list[dict] = []
        self._events: list[list] = []
        self._scene_header: dict = {}
        self._scene_arrays: dict = {}
        self._goals: list[list] = []  # [frame, goal text] each time the observation's goal changes
        self._frame_size = (0, 0)

    # hooks, called by the rollout -------------------------------------------------------------

    def _guard(self, what: str, fn: Callable[[], None]) -> None:
        if self.broken is not None:
            return
        t0 = time.perf_counter()
        try:
            fn()
        except Exception as exc:  # a recorder never stops an episode
            self.broken = f"{what}: {type(exc).__name__}: {exc}"
            _LOG.warning("recording of %s stopped: %s", self.header.get("episode_id"), self.broken)
        finally:
            self.seconds += time.perf_counter() - t0

    def begin(self, env, obs, info) -> None:
        """After ``env.reset``: the scene (floor plan or table) and the first frame."""
        def run():
            if self._scene_probe is not None:
                self._scene_header, self._scene_arrays = self._scene_probe(env, obs, info)
            self._frame(obs, info, 0.0, False)
        self._guard("reset", run)

    def act(self, action) -> None:
        """After ``agent.act``: the action and what the agent's map answered on this frame."""
        def run():
            self._actions.append(np.asarray(action, np.float32).ravel().copy())
            self._snapshot_answers()
        self._guard("action", run)

    def step(self, obs, reward, info) -> None:
        """After ``env.step``: the new frame, reward and success flag."""
        self._guard("step", lambda: self._frame(obs, info, float(reward), bool((info or {}).get("success", False))))

    # internals ---------------------------------------------------------------------------------

    def _frame(self, obs, info, reward: float, success: bool) -> None:
        rgb = np.asarray(obs["rgb"])
        if rgb.ndim != 3 or rgb.shape[2] < 3:
            raise ValueError(f"observation rgb: expected (H, W, 3), got shape {rgb.shape}")
        h, w = rgb.shape[:2]
        if w > self.frame_width:
            rgb = cv2.resize(rgb, (self.frame_width, max(1, round(h * self.frame_width / w))), interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(np.ascontiguousarray(rgb[:, :, :3]), cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise ValueError("observation rgb: JPEG encoding failed")
        state = self._state_probe(obs, info or {}) if self._state_probe is not None else {}
        goal = obs.get("goal") if hasattr(obs, "get") else None
        if isinstance(goal, str) and (not self._goals or self._goals[-1][1] != goal):
            self._goals.append([len(self._jpegs), goal])
        self._jpegs.append(buf.tobytes())
        self._frame_size = (int(rgb.shape[1]), int(rgb.shape[0]))
        self._states.append(state)
        self._rewards.append(reward)
        self._success.append(success)

    def _snapshot_answers(self) -> None:
        answers = getattr(self._mapper, "answers", None) if self._has_answers else None
        if isinstance(answers, Mapping):
            for text, res in list(answers.items()):
                if self._seen.get(text) is res:
                    continue
                self._seen[text] = res
                if text not in self._queries:
                    self._queries.append(text)
                q = self._queries.index(text)
                best = getattr(res, "best", None)
                found = bool(getattr(res, "found", False)) and best is not None
                if found:
                    pts = np.asarray(best.points_n3, np.float64)
                    median = np.median(pts, axis=0).astype(np.float32)
                    box = np.stack([pts.min(axis=0), pts.max(axis=0)]).astype(np.float32)
                else:
                    median, box = np.full(3, np.nan, np.float32), np.full((2, 3), np.nan, np.float32)
                self._current[q] = (int(found), median, box)
                self._events.append([len(self._jpegs) - 1, q, found, "" if found else str(getattr(res, "reason", ""))])
        self._answer_rows.append(dict(self._current))

    def _answer_arrays(self, frames: int) -> dict[str, np.ndarray]:
        q = len(self._queries)
        found = np.full((frames, q), _NO_ANSWER, np.int8)
        median = np.full((frames, q, 3), np.nan, np.float32)
        box = np.full((frames, q, 2, 3), np.nan, np.float32)
        rows = self._answer_rows[:frames]
        rows += [rows[-1] if rows else {}] * (frames - len(rows))  # the last frame keeps the last answers
        for t, row in enumerate(rows):
            for j, (f, m, b) in row.items():
                found[t, j], median[t, j], box[t, j] = f, m, b
        return {"answer_found_tq": found, "answer_median_tq3": median, "answer_box_tq23": box}

    def recording(self, outcome: Mapping | None = None) -> Recording | None:
        """What was recorded so far as a :class:`Recording` (``outcome``: ``status``,
        ``success``, ``metrics``, ``error`` added to the header); None before the first frame."""
        frames = len(self._jpegs)
        if frames == 0:
            return None
        steps = min(len(self._actions), frames - 1)
        offsets = np.zeros(frames + 1, np.int64)
        offsets[1:] = np.cumsum([len(b) for b in self._jpegs])
        actions = np.stack(self._actions[:steps]) if steps else np.zeros((0, 0), np.float32)
        arrays = {
            "frames_jpeg": np.frombuffer(b"".join(self._jpegs), np.uint8),
            "frame_offsets": offsets,
            "actions_ta": actions.astype(np.float32),
            "reward_t": np.asarray(self._rewards, np.float32),
            "success_t": np.asarray(self._success, bool),
            **self._answer_arrays(frames),
            **self._scene_arrays,
        }
        for key in (self._states[0] if self._states else {}):  # a frame without a key keeps the previous value
            rows, value = [], self._states[0][key]
            for state in self._states:
                value = state.get(key, value)
                rows.append(value)
            arrays[key] = np.stack(rows)
        header = {**self.header, "task": self.task, **self._scene_header, "map_answers": self._has_answers,
                  "queries": list(self._queries), "goal_changes": [g for g in self._goals[1:] if g[0] < frames],
                  "answer_events": [e for e in self._events if e[0] < frames], "steps": steps,
                  "frame_size": list(self._frame_size)}
        if self.broken:
            header["recording_stopped"] = self.broken
        for key, value in dict(outcome or {}).items():
            header[key] = value
        return Recording(header, arrays)

    def wants(self, status: str, success: bool) -> str | None:
        """Why the mode asks for this outcome to be written (the header's ``recorded_as``:
        ``"all"``, ``"failure"``, ``"example success"``: the first success of this suite and agent
        label), or None when it does not."""
        failed = status != "ok" or not success
        if self.mode == "all":
            return "all"
        if self.mode != "failures":
            return None
        if failed:
            return "failure"
        return None if success_marker(self.path.parent, self.header).exists() else "example success"

    def finish(self, *, status: str, metrics: Mapping | None = None, error: str | None = None,
               extras: Mapping | None = None) -> list[Path]:
        """Write the recording (and the final map, see :data:`MAP_BUDGET_BYTES`) if the mode
        asks for this outcome; returns the files written (none when it does not, or nothing
        was recorded). ``extras``: the results record's extras, of which :data:`OUTCOME_EXTRAS`
        (goal text, stop reason, success radius) go into the header. An example success also
        writes its :func:`success_marker`. Writing problems are logged, never raised."""
        t0 = time.perf_counter()
        try:
            success = bool((metrics or {}).get("success", False))
            why = self.wants(status, success)
            if why is None:
                return []
            outcome = {"status": status, "success": success, "metrics": _jsonable(dict(metrics or {})), "error": error,
                       "recorded_as": why,
                       **{k: _jsonable(v) for k, v in dict(extras or {}).items() if k in OUTCOME_EXTRAS and v is not None}}
            rec = self.recording(outcome)
            if rec is None:
                return []
            rec.header["map"] = self._save_map()
            self.written.append(save_recording(rec, self.path))
            if why == "example success":
                marker = success_marker(self.path.parent, self.header)
                atomic_write_text(marker, json.dumps({"suite": self.header["suite"], "agent": _label(self.header),
                                                      "recording": self.path.name}) + "\n")
            return list(self.written)
        except Exception as exc:  # disk full, a map that cannot be saved: the episode's record stands
            _LOG.warning("recording of %s not written: %s: %s", self.header.get("episode_id"), type(exc).__name__, exc)
            return list(self.written)
        finally:
            self.seconds += time.perf_counter() - t0

    def _save_map(self) -> dict:
        mapper = getattr(self.agent, "mapper", None)
        the_map = getattr(mapper, "map", None)
        if the_map is None or not hasattr(the_map, "state_dict"):
            return {"skipped": "the agent keeps no map"}
        if not getattr(getattr(mapper, "config", None), "persistent", False):
            return {"skipped": "the agent's map holds its current frame only"}
        size = int(the_map.nbytes()) if hasattr(the_map, "nbytes") else sum(a.nbytes for a in the_map.state_dict()[1].values())
        info: dict = {}
        if size > MAP_BUDGET_BYTES:
            if not isinstance(the_map, PointFusionMap) or len(the_map) == 0:
                return {"skipped": f"the final map ({size / 2**20:.0f} MB) is over the {MAP_BUDGET_BYTES / 2**20:.0f} MB budget "
                                   "of a recording; its answers are recorded"}
            max_points = int(len(the_map) * MAP_BUDGET_BYTES / size)
            thinned = thin_map(the_map, max(1, max_points))
            while thinned.map.nbytes() > MAP_BUDGET_BYTES and max_points > 1:  # the bank's share did not shrink as fast
                max_points //= 2
                thinned = thin_map(the_map, max(1, max_points))
            if thinned.map.nbytes() > MAP_BUDGET_BYTES:
                return {"skipped": f"the final map ({size / 2**20:.0f} MB) does not fit the {MAP_BUDGET_BYTES / 2**20:.0f} MB "
                                   "budget of a recording even thinned; its answers are recorded"}
            info = {"thinned_from": thinned.original_points, "voxel_m": thinned.voxel}
            the_map = thinned.map
        out = self.path.with_name(self.path.name[: -len(".npz")] + MAP_SUFFIX)
        self.written.append(save_map(the_map, out, meta=map_meta(mapper, self.header.get("agent"))))
        return {"file": out.name, "points": int(len(the_map.points)), "bytes": int(out.stat().st_size), **info}


def map_meta(mapper, agent: str | None = None) -> dict:
    """What a saved map records of how it was made and asked (its ``meta``): the mapper's own
    (:meth:`conceptfusion.mapper.ConceptMapper.meta`: encoder, proposer, setting, floor, the
    lookup its agent used) and the agent; ``{}`` (plus the agent) for a mapper without one."""
    meta = dict(mapper.meta()) if callable(getattr(mapper, "meta", None)) else {}
    if isinstance(agent, str) and agent:
        meta["agent"] = agent
    return meta


def _label(header: Mapping) -> str:
    return str(header.get("agent_label") or header["agent"])


def success_marker(replays_dir: str | os.PathLike, header: Mapping) -> Path:
    """The file in a replays folder that says which success of ``header``'s suite and agent
    label the ``"failures"`` mode kept: ``.success__<suite>__<agent label>.json`` (each part
    reduced to ``[A-Za-z0-9._-]``; hidden, so that listings of recordings and videos skip it)."""
    part = [re.sub(r"[^A-Za-z0-9._-]+", "-", str(v)).strip("-.") or "x" for v in (header["suite"], _label(header))]
    return Path(replays_dir) / f".success__{part[0]}__{part[1]}.json"


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(float(value)) else None
    return value if value is None or isinstance(value, str) else str(value)
