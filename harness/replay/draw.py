"""Drawing one video frame of a recording: what the agent saw, where it was, and why it ended.

A frame (:func:`draw_frame`, :data:`FRAME_SHAPE`) is, top to bottom:

* a banner with the goal as the agent was told it at that step (big enough to read in a
  report's thumbnail; a long instruction wraps onto two lines);
* the camera frame of that step (left) beside a top-down view (right): for object search the
  floor plan, the path so far, the base and its heading, the goal object's box and the success
  region around it; for tabletop rearrangement the table, the line, every object where it
  started (hollow) and where it is now (filled; targets in colour) and the pushes so far; both
  with the region the map answered (box and median);
* text lines: the step; how far the episode is from success (search: "2.31 m to goal (success
  within 1.00 m)"; rearrange: each target's distance past the line on its side, and how far the
  other objects moved); the map's answer at that step (found where, how far from the goal, or
  not found and why); on the last frame the outcome and why the episode stopped;
* a legend: the colour of each mark of the top-down view.

Drawn with OpenCV in BGR; :func:`draw_frame` returns RGB.
"""

from __future__ import annotations

import math
import textwrap

import cv2
import numpy as np

from harness.replay.captions import FrameText
from harness.replay.record import Recording

__all__ = ["FRAME_SHAPE", "draw_frame", "Renderer"]

_W = 640  # frame width (px): camera and top-down panels of 320 each
_CAM_W = _TOP_W = _W // 2
_BANNER = 44  # goal banner
_H = 240  # panel height
_LINE_H = 16
_INFO_LINES = 6
_INFO = _INFO_LINES * _LINE_H + 6
_LEGEND = 22
FRAME_SHAPE = (_BANNER + _H + _INFO + _LEGEND, _W, 3)
"""(height, width, 3) of every video frame: both even, as H.264 in yuv420p needs."""

_FONT = cv2.FONT_HERSHEY_SIMPLEX
# BGR colours
_WHITE, _BLACK, _GREY, _DARK = (255, 255, 255), (0, 0, 0), (170, 170, 170), (90, 90, 90)
_BANNER_BG, _WALL = (70, 45, 25), (110, 110, 110)
_PATH, _ROBOT, _START = (200, 110, 30), (40, 40, 220), (60, 170, 60)
_GOAL, _RING, _ANSWER, _PUSH = (40, 40, 200), (0, 140, 255), (200, 40, 200), (200, 160, 0)
_TABLE, _LINE = (120, 160, 200), (0, 220, 240)
_OK_TEXT, _BAD_TEXT = (0, 130, 0), (0, 0, 190)
_TONE = {"plain": _BLACK, "dim": _DARK, "ok": _OK_TEXT, "bad": _BAD_TEXT, "answer": _ANSWER}


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


def _text(img, text: str, org, color=_BLACK, scale: float = 0.42, thickness: int = 1) -> None:
    cv2.putText(img, text, org, _FONT, scale, color, thickness, cv2.LINE_AA)


def _width(text: str, scale: float, thickness: int = 1) -> int:
    return cv2.getTextSize(text, _FONT, scale, thickness)[0][0]


def _fit(text: str, width: int, scale: float = 0.42) -> str:
    """``text`` cut (ending in ``~``) to at most ``width`` pixels."""
    if _width(text, scale) <= width:
        return text
    while text and _width(text + "~", scale) > width:
        text = text[:-1]
    return text + "~"


def _rounded_box(lo_2, hi_2, r: float, arc: int = 8) -> np.ndarray:
    """Outline (N, 2) of the points within ``r`` of the box ``[lo, hi]``: the box grown by ``r``
    with round corners."""
    (x0, y0), (x1, y1) = lo_2, hi_2
    pts = []
    for (cx, cy), a0 in (((x1, y0), -90), ((x1, y1), 0), ((x0, y1), 90), ((x0, y0), 180)):
        a = np.radians(a0 + np.linspace(0, 90, arc))
        pts.append(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1))
    return np.concatenate(pts)


class Renderer:
    """Draws the frames of one recording: the static parts (background, view, legend) once,
    :meth:`frame` per step."""

    def __init__(self, rec: Recording) -> None:
        self.rec, a = rec, rec.arrays
        self.text = FrameText(rec)
        self.search, self.rearrange = self.text.search, self.text.rearrange
        self.actions = a["actions_ta"]
        self.last = rec.num_frames - 1
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
        if self.rearrange:
            for xy, rad in zip(a["objects_tn2"][0], self._object_radius()):
                cv2.circle(self.bg, self.view.pt(xy), max(2, int(rad * self.view.scale)), _DARK, 1, cv2.LINE_AA)
        self.legend = self._legend()

    # per recording ----------------------------------------------------------------------------

    def _object_radius(self) -> np.ndarray:
        a = self.rec.arrays
        return a.get("object_radius_n", np.full(a["objects_tn2"].shape[1], 0.03, np.float32))

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
        img = np.where(blocked[::-1, :, None], np.uint8(_WALL[0]), np.uint8(255)).repeat(3, axis=2)
        full = cv2.resize(img, (gu1 - gu0, gv1 - gv0), interpolation=cv2.INTER_AREA)
        u0, v0, u1, v1 = max(gu0, 0), max(gv0, 0), min(gu1, _TOP_W), min(gv1, _H)
        if u1 > u0 and v1 > v0:
            self.bg[v0:v1, u0:u1] = full[v0 - gv0:v1 - gv0, u0 - gu0:u1 - gu0]

    def _legend(self) -> np.ndarray:
        """The legend row: a swatch and a word for each mark of the top-down view."""
        if self.search:
            items = [("fill", _WALL, "wall"), ("line", _PATH, "path"), ("dot", _START, "start"),
                     ("ring", _ROBOT, "robot+heading"), ("box", _GOAL, "goal object"),
                     ("poly", _RING, "success region"), ("cross", _ANSWER, "map's answer")]
        elif self.rearrange:
            items = [("line", _LINE, "line"), ("dot", _GOAL, "target"), ("dot", _GREY, "other object"),
                     ("ring", _DARK, "start"), ("arrow", _PUSH, "push"), ("arrow", _ROBOT, "last push"),
                     ("cross", _ANSWER, "map's answer")]
        else:
            items = [("cross", _ANSWER, "map's answer")]
        img = np.full((_LEGEND, _W, 3), 255, np.uint8)
        cv2.line(img, (0, 0), (_W - 1, 0), _GREY, 1)
        scale = 0.38
        while scale > 0.28 and 8 + sum(22 + _width(label, scale) + 12 for _, _, label in items) > _W:
            scale -= 0.02
        x, mid = 8, _LEGEND // 2 + 1
        for kind, color, label in items:
            c = (x + 8, mid)
            if kind == "fill":
                cv2.rectangle(img, (x + 1, mid - 6), (x + 15, mid + 6), color, -1)
            elif kind == "line":
                cv2.line(img, (x, mid), (x + 16, mid), color, 3, cv2.LINE_AA)
            elif kind == "dot":
                cv2.circle(img, c, 6, color, -1, cv2.LINE_AA)
            elif kind == "ring":
                cv2.circle(img, c, 6, color, 2, cv2.LINE_AA)
            elif kind == "box":
                cv2.rectangle(img, (x + 2, mid - 6), (x + 14, mid + 6), color, 2)
            elif kind == "poly":
                cv2.ellipse(img, c, (8, 6), 0, 0, 360, color, 1, cv2.LINE_AA)
            elif kind == "arrow":
                cv2.arrowedLine(img, (x, mid), (x + 16, mid), color, 2, cv2.LINE_AA, tipLength=0.4)
            elif kind == "cross":
                cv2.drawMarker(img, c, color, cv2.MARKER_CROSS, 12, 2, cv2.LINE_AA)
            _text(img, label, (x + 22, mid + 4), _BLACK, scale)
            x += 22 + _width(label, scale) + 12
        return img

    # per frame -------------------------------------------------------------------------------

    def topdown(self, t: int) -> np.ndarray:
        img, a, v = self.bg.copy(), self.rec.arrays, self.view
        box = self.text.goal_box(t)
        if box is not None and np.all(np.isfinite(box)):
            ring = v.px(_rounded_box(box[0, :2], box[1, :2], self.text.radius))
            cv2.polylines(img, [ring.reshape(-1, 1, 2)], True, _RING, 1, cv2.LINE_AA)
            cv2.rectangle(img, v.pt(box[0, :2]), v.pt(box[1, :2]), _GOAL, 2)
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
            for i, (xy, rad) in enumerate(zip(a["objects_tn2"][t], self._object_radius())):
                cv2.circle(img, v.pt(xy), max(2, int(rad * v.scale)), _GOAL if i in targets else _GREY, -1, cv2.LINE_AA)
            if self.pushes is not None:
                for k, seg in enumerate(self.pushes[:t]):
                    if np.all(np.isfinite(seg)):
                        cv2.arrowedLine(img, v.pt(seg[:2]), v.pt(seg[2:]), _ROBOT if k == t - 1 else _PUSH, 2, cv2.LINE_AA,
                                        tipLength=0.2)
        for _, found, median, box in self.text.answers(t):
            if found == 1 and np.all(np.isfinite(box)):
                cv2.rectangle(img, v.pt(box[0, :2]), v.pt(box[1, :2]), _ANSWER, 1, cv2.LINE_AA)
                cv2.drawMarker(img, v.pt(median[:2]), _ANSWER, cv2.MARKER_CROSS, 12, 2, cv2.LINE_AA)
        if t == self.last:
            word, ok = self.text.verdict()
            color = _OK_TEXT if ok else _BAD_TEXT
            size = cv2.getTextSize(word, _FONT, 0.8, 2)[0]
            cv2.rectangle(img, (_TOP_W - size[0] - 16, 4), (_TOP_W - 4, 12 + size[1] + 8), _WHITE, -1)
            _text(img, word, (_TOP_W - size[0] - 10, 12 + size[1]), color, 0.8, 2)
        return img

    def banner(self, t: int) -> np.ndarray:
        """The goal banner: ``Goal: ...`` in white on dark blue, one line or two."""
        img = np.full((_BANNER, _W, 3), _BANNER_BG, np.uint8)
        text = self.text.goal(t)
        if _width(text, 0.7, 2) <= _W - 16:
            _text(img, text, (8, 30), _WHITE, 0.7, 2)
            return img
        lines = textwrap.wrap(text, width=max(10, len(text) // 2 + 4))[:3]
        first, rest = lines[0], " ".join(lines[1:])
        for row, line in enumerate((first, rest)):
            _text(img, _fit(line, _W - 16, 0.52), (8, 18 + 19 * row), _WHITE, 0.52)
        return img

    def strip(self, t: int) -> np.ndarray:
        """The text lines under the panels on frame ``t``."""
        img = np.full((_INFO, _W, 3), 245, np.uint8)
        lines = self.text.styled(t)
        if len(lines) > _INFO_LINES:  # keep the outcome on the last frame
            lines = lines[:_INFO_LINES - 1] + lines[-1:] if t == self.last else lines[:_INFO_LINES]
        for row, (text, tone) in enumerate(lines):
            last_row = t == self.last and row == len(lines) - 1  # the outcome, in bold
            scale = 0.45 if last_row else 0.42
            _text(img, _fit(text, _W - 12, scale), (6, 14 + row * _LINE_H), _TONE[tone], scale, 2 if last_row else 1)
        return img

    def frame(self, t: int) -> np.ndarray:
        """Video frame ``t``: :data:`FRAME_SHAPE` uint8 BGR."""
        cam_rgb = self.rec.frame_rgb(t)
        cam = cv2.resize(np.ascontiguousarray(cam_rgb[:, :, ::-1]), (_CAM_W, _H), interpolation=cv2.INTER_LINEAR)
        top = self.topdown(t)
        cv2.line(top, (0, 0), (0, _H - 1), _DARK, 1)
        return np.concatenate([self.banner(t), np.concatenate([cam, top], axis=1), self.strip(t), self.legend], axis=0)


def draw_frame(recording: Recording, t: int) -> np.ndarray:
    """Video frame ``t`` of a recording: goal banner, camera beside top-down view, text lines, legend.

    Shape:
        returns :data:`FRAME_SHAPE` (408, 640, 3) uint8, RGB.
    """
    if not 0 <= t < recording.num_frames:
        raise IndexError(f"frame: expected an index in [0, {recording.num_frames}), got {t}")
    return np.ascontiguousarray(Renderer(recording).frame(t)[:, :, ::-1])
