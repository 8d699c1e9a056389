"""Turning a recording into a video: the agent's camera beside a top-down view.

Each video frame (:func:`draw_frame`) is the camera frame of that step (left) beside a top-down
view (right): for object search the floor plan with the path so far, the base and its heading,
the goal object's box and success ring; for tabletop rearrangement the table, the line, every
object where it started (hollow) and where it is now (filled; targets in colour) and the pushes
so far. Both show what the map answered (the best region's box and median, or "not found"), and a
text strip gives the goal, the step and the outcome. Drawn with OpenCV.

:func:`render_video` writes MP4 through ``cv2.VideoWriter`` (``mp4v``); when that writer cannot
be opened, a GIF through Pillow. :func:`render_missing_videos` renders every recording of a run
folder that has no video yet.
"""

from __future__ import annotations

import io
import logging
import math
import os
from pathlib import Path

import cv2
import numpy as np

from conceptfusion.errors import ConceptFusionError, MissingDependencyError
from conceptfusion.io_utils import atomic_write_bytes
from harness.replay.record import Recording, is_recording_file, load_recording
from harness.report.paths import REPLAYS_DIR, VIDEO_SUFFIXES

__all__ = ["draw_frame", "render_video", "render_missing_videos", "render_videos_of", "video_path", "default_fps"]

_LOG = logging.getLogger(__name__)

_H = 240  # panel height (px)
_CAM_W = 320
_TOP_W = 320
_STRIP = 60  # text rows under the panels
_FONT = cv2.FONT_HERSHEY_SIMPLEX
# BGR colours
_WHITE, _BLACK, _GREY, _DARK = (255, 255, 255), (0, 0, 0), (170, 170, 170), (90, 90, 90)
_PATH, _ROBOT, _START = (200, 110, 30), (40, 40, 220), (60, 170, 60)
_GOAL, _ANSWER, _PUSH = (40, 40, 200), (200, 40, 200), (200, 160, 0)
_TABLE, _LINE = (120, 160, 200), (0, 220, 240)


def default_fps(recording: Recording) -> float:
    """Frames per second of a recording's video: 4 for search (a step is 0.5 s of driving), 1 for
    tabletop pushes (a step is a whole push)."""
    return 1.0 if recording.task == "tabletop_rearrange" else 4.0


def video_path(recording_path: str | os.PathLike) -> Path | None:
    """The existing video of a recording (``<stem>.mp4`` or ``<stem>.gif`` beside it), or None."""
    p = Path(recording_path)
    for suffix in VIDEO_SUFFIXES:
        v = p.with_suffix(suffix)
        if v.is_file() and v.stat().st_size > 0:
            return v
    return None


class _View:
    """World xy (metres) -> pixel of a panel, equal scale, y up."""

    def __init__(self, lo, hi, width: int, height: int, pad: int = 8) -> None:
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        span = np.maximum(hi - lo, 1e-6)
        self.scale = min((width - 2 * pad) / span[0], (height - 2 * pad) / span[1])
        self.off = np.array([(width - span[0] * self.scale) / 2, (height - span[1] * self.scale) / 2])
        self.lo, self.height = lo, height

    def px(self, xy) -> np.ndarray:
        """(..., 2) world -> (..., 2) int32 pixel."""
        xy = np.asarray(xy, np.float64)
        u = self.off[0] + (xy[..., 0] - self.lo[0]) * self.scale
        v = self.height - (self.off[1] + (xy[..., 1] - self.lo[1]) * self.scale)
        return np.stack([u, v], axis=-1).round().astype(np.int32)

    def pt(self, xy) -> tuple[int, int]:
        u, v = self.px(np.asarray(xy, np.float64)[:2])
        return int(u), int(v)


def _text(img, text: str, org, color=_BLACK, scale: float = 0.4) -> None:
    cv2.putText(img, text, org, _FONT, scale, color, 1, cv2.LINE_AA)


def _fit(text: str, width: int, scale: float = 0.4) -> str:
    while text and cv2.getTextSize(text, _FONT, scale, 1)[0][0] > width:
        text = text[:-2]
        if len(text) > 3:
            text = text[:-1] + "~"
    return text


class _Renderer:
    """Static parts (background, view) computed once per recording; :meth:`frame` per step."""

    def __init__(self, rec: Recording) -> None:
        self.rec, a = rec, rec.arrays
        self.search = "pose_t3" in a
        self.rearrange = "objects_tn2" in a
        self.actions = a["actions_ta"]
        self.pushes = self._pushes()
        self.bg = np.full((_H, _TOP_W, 3), 255, np.uint8)
        lo, hi = self._bounds()
        self.view = _View(lo, hi, _TOP_W, _H)
        if self.search and "floor_blocked_hw" in a:
            self._draw_floor()
        elif self.rearrange and "table_xy_22" in a:
            t = a["table_xy_22"]
            cv2.rectangle(self.bg, self.view.pt(t[0]), self.view.pt(t[1]), _TABLE, -1)
        if "line_22" in a:
            cv2.line(self.bg, self.view.pt(a["line_22"][0]), self.view.pt(a["line_22"][1]), _LINE, 3, cv2.LINE_AA)
        if "goal_box_23" in a:
            box = a["goal_box_23"]
            ring = float(rec.header.get("success_distance", 1.0))
            centre = (box[0, :2] + box[1, :2]) / 2
            r = int(round((ring + float(np.max(box[1, :2] - box[0, :2])) / 2) * self.view.scale))
            cv2.circle(self.bg, self.view.pt(centre), r, (200, 200, 255), 1, cv2.LINE_AA)
            cv2.rectangle(self.bg, self.view.pt(box[0, :2]), self.view.pt(box[1, :2]), _GOAL, 2)
        if self.rearrange:
            radius = a.get("object_radius_n", np.full(a["objects_tn2"].shape[1], 0.03, np.float32))
            for xy, rad in zip(a["objects_tn2"][0], radius):
                cv2.circle(self.bg, self.view.pt(xy), max(2, int(rad * self.view.scale)), _DARK, 1, cv2.LINE_AA)

    def _pushes(self) -> np.ndarray | None:
        """Rearrange: per step the push segment (start xy, end xy), NaN for a stop; (T, 4)."""
        if not self.rearrange or self.actions.ndim != 2 or self.actions.shape[1] < 5:
            return None
        a = self.actions.astype(np.float64)
        end = a[:, :2] + a[:, 3:4] * np.stack([np.cos(a[:, 2]), np.sin(a[:, 2])], axis=1)
        seg = np.concatenate([a[:, :2], end], axis=1)
        seg[a[:, 4] > 0.5] = np.nan
        return seg

    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        a, pts = self.rec.arrays, []
        if self.search:
            if "floor_blocked_hw" in a:
                floor = self.rec.header.get("floor", {})
                origin, cell = np.asarray(floor.get("origin", (0, 0)), np.float64), float(floor.get("cell", 0.05))
                h, w = a["floor_blocked_hw"].shape
                pts += [origin, origin + (w * cell, h * cell)]
            pts += list(a["pose_t3"][:, :2])
            if "goal_box_23" in a:
                pts += [a["goal_box_23"][0, :2], a["goal_box_23"][1, :2]]
        elif self.rearrange:
            if "table_xy_22" in a:
                pts += list(a["table_xy_22"] + [[-0.05, -0.05], [0.05, 0.05]])
            pts += list(a["objects_tn2"].reshape(-1, 2))
        pts = [p for p in pts if np.all(np.isfinite(p))]
        if not pts:
            return np.array([-1.0, -1.0]), np.array([1.0, 1.0])
        pts = np.asarray(pts, np.float64)
        return pts.min(axis=0), pts.max(axis=0)

    def _draw_floor(self) -> None:
        a, floor = self.rec.arrays, self.rec.header.get("floor", {})
        blocked = a["floor_blocked_hw"]
        origin, cell = np.asarray(floor.get("origin", (0, 0)), np.float64), float(floor.get("cell", 0.05))
        h, w = blocked.shape
        # the grid's pixel rectangle (row 0 is the lowest y, drawn at the bottom), pasted clipped
        (gu0, gv1), (gu1, gv0) = self.view.pt(origin), self.view.pt(origin + (w * cell, h * cell))
        if gu1 - gu0 < 1 or gv1 - gv0 < 1:
            return
        img = np.where(blocked[::-1, :, None], np.uint8(110), np.uint8(255)).repeat(3, axis=2)
        full = cv2.resize(img, (gu1 - gu0, gv1 - gv0), interpolation=cv2.INTER_AREA)
        u0, v0, u1, v1 = max(gu0, 0), max(gv0, 0), min(gu1, _TOP_W), min(gv1, _H)
        if u1 > u0 and v1 > v0:
            self.bg[v0:v1, u0:u1] = full[v0 - gv0:v1 - gv0, u0 - gu0:u1 - gu0]

    # per frame -------------------------------------------------------------------------------

    def answers(self, t: int) -> list[tuple[str, int, np.ndarray, np.ndarray]]:
        a = self.rec.arrays
        return [(q, int(a["answer_found_tq"][t, j]), a["answer_median_tq3"][t, j], a["answer_box_tq23"][t, j])
                for j, q in enumerate(self.rec.queries)]

    def topdown(self, t: int) -> np.ndarray:
        img, a, v = self.bg.copy(), self.rec.arrays, self.view
        if self.search:
            path = v.px(a["pose_t3"][: t + 1, :2])
            if len(path) > 1:
                cv2.polylines(img, [path.reshape(-1, 1, 2)], False, _PATH, 2, cv2.LINE_AA)
            cv2.circle(img, tuple(int(c) for c in path[0]), 4, _START, -1, cv2.LINE_AA)
            x, y, yaw = a["pose_t3"][t]
            r = max(3, int(0.25 * v.scale))
            cv2.circle(img, v.pt((x, y)), r, _ROBOT, 2, cv2.LINE_AA)
            cv2.line(img, v.pt((x, y)), v.pt((x + 0.45 * math.cos(yaw), y + 0.45 * math.sin(yaw))), _ROBOT, 2, cv2.LINE_AA)
        if self.rearrange:
            targets = set(self.rec.header.get("objects", {}).get("targets", []))
            radius = a.get("object_radius_n", np.full(a["objects_tn2"].shape[1], 0.03, np.float32))
            for i, (xy, rad) in enumerate(zip(a["objects_tn2"][t], radius)):
                color = _GOAL if i in targets else _GREY
                cv2.circle(img, v.pt(xy), max(2, int(rad * v.scale)), color, -1, cv2.LINE_AA)
            if self.pushes is not None:
                for k, seg in enumerate(self.pushes[:t]):
                    if np.all(np.isfinite(seg)):
                        cv2.arrowedLine(img, v.pt(seg[:2]), v.pt(seg[2:]), _ROBOT if k == t - 1 else _PUSH, 2, cv2.LINE_AA,
                                        tipLength=0.2)
        for _, found, median, box in self.answers(t):
            if found == 1 and np.all(np.isfinite(box)):
                cv2.rectangle(img, v.pt(box[0, :2]), v.pt(box[1, :2]), _ANSWER, 1, cv2.LINE_AA)
                c = v.pt(median[:2])
                cv2.drawMarker(img, c, _ANSWER, cv2.MARKER_CROSS, 12, 2, cv2.LINE_AA)
        return img

    def strip(self, t: int, width: int) -> np.ndarray:
        h, rec = self.rec.header, self.rec
        img = np.full((_STRIP, width, 3), 245, np.uint8)
        last = t == rec.num_frames - 1
        outcome = ""
        if last:
            outcome = "SUCCESS" if h.get("success") else ("FAILED" if h.get("status", "ok") == "ok" else str(h.get("status")).upper())
        status = f"step {t}/{rec.num_frames - 1}  {h.get('agent_label', h.get('agent'))}  {h.get('episode_id')}"
        _text(img, _fit(status, width - 80), (6, 16))
        _text(img, _fit(f"goal: {h.get('goal', h.get('instruction', ''))}", width - 12), (6, 34))
        if outcome:
            _text(img, outcome, (width - 74, 16), (0, 140, 0) if h.get("success") else (0, 0, 200), 0.45)
        parts = []
        for q, found, median, _ in self.answers(t):
            if found == 1:
                parts.append(f"'{q}': found at ({median[0]:.2f}, {median[1]:.2f})")
            elif found == 0:
                parts.append(f"'{q}': not found")
        if parts:
            text = "map: " + "; ".join(parts)
        else:
            text = "map: not asked yet" if h.get("map_answers", bool(rec.queries)) else "map: the agent keeps none"
        _text(img, _fit(text, width - 12), (6, 52), _ANSWER if parts else _DARK)
        return img

    def frame(self, t: int) -> np.ndarray:
        """Video frame ``t``: (240 + 60, 640, 3) uint8 BGR."""
        cam_rgb = self.rec.frame_rgb(t)
        cam = cv2.resize(np.ascontiguousarray(cam_rgb[:, :, ::-1]), (_CAM_W, _H), interpolation=cv2.INTER_LINEAR)
        top = self.topdown(t)
        cv2.line(top, (0, 0), (0, _H - 1), _DARK, 1)
        panels = np.concatenate([cam, top], axis=1)
        return np.concatenate([panels, self.strip(t, panels.shape[1])], axis=0)


def draw_frame(recording: Recording, t: int) -> np.ndarray:
    """Video frame ``t`` of a recording: camera beside top-down view over a text strip.

    Shape:
        returns (300, 640, 3) uint8, RGB.
    """
    if not 0 <= t < recording.num_frames:
        raise IndexError(f"frame: expected an index in [0, {recording.num_frames}), got {t}")
    return np.ascontiguousarray(_Renderer(recording).frame(t)[:, :, ::-1])


def _write_mp4(frames, path: Path, fps: float, size: tuple[int, int]) -> bool:
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), size)
    if not writer.isOpened():
        writer.release()
        tmp.unlink(missing_ok=True)
        return False
    try:
        for f in frames:
            writer.write(f)
    finally:
        writer.release()
    if not tmp.is_file() or tmp.stat().st_size == 0:
        tmp.unlink(missing_ok=True)
        return False
    os.replace(tmp, path)
    return True


def _write_gif(frames, path: Path, fps: float) -> None:
    try:
        from PIL import Image
    except ImportError as exc:
        raise MissingDependencyError("a GIF replay needs Pillow: pip install pillow") from exc
    images = [Image.fromarray(np.ascontiguousarray(f[:, :, ::-1])) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=int(round(1000 / fps)), loop=0)
    atomic_write_bytes(path, buf.getvalue())


def render_video(recording: Recording | str | os.PathLike, out: str | os.PathLike | None = None, *,
                 fps: float | None = None) -> Path:
    """Render a recording (or the recording file at a path) to a video; returns its path.

    ``out``: the video file, ``.mp4`` or ``.gif`` (default: the recording's path with ``.mp4``;
    needed when ``recording`` is a :class:`Recording`). An ``.mp4`` goes through
    ``cv2.VideoWriter`` (``mp4v``); when that writer cannot be opened, the video is written as a
    GIF (Pillow) beside it instead, and that path is returned. One video frame per recorded frame,
    at ``fps`` (default :func:`default_fps`).

    Raises:
        ValueError: ``out`` with another ending, ``fps`` <= 0, or no ``out`` for a Recording.
        ReplayFormatError, MissingFileError: from :func:`~harness.replay.record.load_recording`.
    """
    if isinstance(recording, Recording):
        rec = recording
        if out is None:
            raise ValueError("render_video: expected out= (a .mp4 or .gif path) for a Recording")
    else:
        rec = load_recording(recording)
        if out is None:
            out = Path(recording).with_suffix(".mp4")
    out = Path(out)
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video: expected a file ending in {' or '.join(VIDEO_SUFFIXES)}, got {out.name!r}")
    fps = default_fps(rec) if fps is None else float(fps)
    if not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps: expected a number > 0, got {fps!r}")
    renderer = _Renderer(rec)
    first = renderer.frame(0)
    size = (first.shape[1], first.shape[0])
    out.parent.mkdir(parents=True, exist_ok=True)

    def frames():
        yield first
        for t in range(1, rec.num_frames):
            yield renderer.frame(t)

    if out.suffix.lower() == ".mp4":
        if _write_mp4(frames(), out, fps, size):
            return out
        _LOG.info("the MP4 writer did not open; writing a GIF instead")
        out = out.with_suffix(".gif")
    _write_gif(list(frames()), out, fps)
    return out


def render_missing_videos(run_dir: str | os.PathLike) -> list[Path]:
    """Render a video for every recording in ``run_dir/replays/`` that has none yet; returns the
    videos written. A recording that cannot be read is logged and skipped (the report goes on)."""
    folder = Path(run_dir) / REPLAYS_DIR
    if not folder.is_dir():
        return []
    return render_videos_of(p for p in sorted(folder.glob("*.npz")) if video_path(p) is None)


def render_videos_of(paths) -> list[Path]:
    """Render the video of every recording file among ``paths`` (what
    :meth:`~harness.replay.record.EpisodeRecorder.finish` returns); returns the videos written.
    Episode jobs call it in their worker, so that a run's videos are made alongside its episodes
    rather than one after another by the report (35-40 s of one core for the default
    comparison's failures). A recording that cannot be drawn is logged and skipped; the report
    tries again (:func:`render_missing_videos`)."""
    written = []
    for path in paths:
        path = Path(path)
        if not is_recording_file(path):
            continue
        try:
            written.append(render_video(path))
        except (ConceptFusionError, OSError, ValueError) as exc:
            _LOG.warning("no video for %s: %s", path, exc)
    return written
