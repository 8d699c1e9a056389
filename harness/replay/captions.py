"""What each video frame of a recording says, as text: the goal, how far the episode is from
success, what the map answered, and on the last frame the outcome and why the episode stopped.

:class:`FrameText` reads a :class:`~harness.replay.record.Recording` (older recordings too:
what they lack is worked out from the poses, the goal's box and the line) and gives the lines of
frame ``t`` with a tone each (:data:`TONES`); :mod:`harness.replay.draw` picks their colours.
"""

from __future__ import annotations

import math

import numpy as np

from harness.replay.record import Recording
from sim_envs.envs.rearrange_eval import DISTRACTOR_TOLERANCE, SIDE_MARGIN, VIEW_DIR

__all__ = ["TONES", "FrameText", "box_distance_xy"]

TONES = ("plain", "dim", "ok", "bad", "answer")
"""How a line reads: plain, dim (context), ok (success holds), bad (a failure), answer (the map's)."""


def box_distance_xy(xy_n2, lo_2, hi_2) -> np.ndarray:
    """Horizontal distance (m) of points to an axis-aligned box (0 inside).

    Shape:
        xy_n2: (..., 2); lo_2, hi_2: (..., 2) broadcast with it. returns: (...,).
    """
    d = np.maximum(np.maximum(np.asarray(lo_2) - xy_n2, 0.0), np.asarray(xy_n2) - np.asarray(hi_2))
    return np.linalg.norm(d, axis=-1)


def _cm(metres: float) -> str:
    return f"{100 * metres:.1f} cm"


class FrameText:
    """The text of each frame of one recording (per-recording facts worked out once)."""

    def __init__(self, rec: Recording) -> None:
        self.rec, a, h = rec, rec.arrays, rec.header
        self.search = "pose_t3" in a
        self.rearrange = "objects_tn2" in a
        self.actions = a["actions_ta"]
        self.last = rec.num_frames - 1
        self.radius = float(h.get("success_radius", h.get("success_distance", 1.0)))
        """Search: the success radius (m) around the goal object's box."""
        self.goal_distance = self._goal_distance()
        """Search: the base's distance to the current goal per frame (T + 1,), or None."""
        self.past_line = self._past_line()
        """Rearrange: each target's distance past the line on its side per frame (T + 1, K), or None."""

    # per recording ----------------------------------------------------------------------------

    def goal_box(self, t: int) -> np.ndarray | None:
        """Search: the current goal object's box (2, 3) on frame ``t`` (a chain's goals one after
        the other; older recordings: the first goal's), or None."""
        a = self.rec.arrays
        if "goal_box_t23" in a:
            return a["goal_box_t23"][t]
        return a.get("goal_box_23") if self.search else None

    def _goal_distance(self) -> np.ndarray | None:
        """As the environment measured it (``goal_distance_t``), else (older recordings) from the
        pose and the goal's box."""
        a = self.rec.arrays
        if "goal_distance_t" in a:
            return a["goal_distance_t"].astype(np.float64)
        if self.search and self.goal_box(0) is not None:
            boxes = np.stack([self.goal_box(t) for t in range(self.rec.num_frames)])
            return box_distance_xy(a["pose_t3"][:, :2], boxes[:, 0, :2], boxes[:, 1, :2])
        return None

    def _past_line(self) -> np.ndarray | None:
        """As the environment judged it (``target_past_line_tk``), else (older recordings) from
        the objects' xy and the line (negative: on the wrong side)."""
        a, objects = self.rec.arrays, self.rec.header.get("objects", {})
        if "target_past_line_tk" in a:
            return a["target_past_line_tk"].astype(np.float64)
        targets, sides = objects.get("targets", []), objects.get("sides", [])
        if not self.rearrange or "line_22" not in a or len(targets) != len(sides) or not targets:
            return None
        p0, p1 = a["line_22"].astype(np.float64)
        d = (p1 - p0) / max(float(np.linalg.norm(p1 - p0)), 1e-9)
        normal = np.array([-d[1], d[0]])
        if normal @ np.array([VIEW_DIR[1], -VIEW_DIR[0]]) < 0:  # point it to the viewer's right
            normal = -normal
        sign = np.array([1.0 if s == "right" else -1.0 for s in sides])
        return ((a["objects_tn2"][:, targets].astype(np.float64) - p0) @ normal) * sign

    # per frame -------------------------------------------------------------------------------

    def answers(self, t: int) -> list[tuple[str, int, np.ndarray, np.ndarray]]:
        """Per query: (text, found 1/0/-1, median (3,), box (2, 3)) on frame ``t``."""
        a = self.rec.arrays
        return [(q, int(a["answer_found_tq"][t, j]), a["answer_median_tq3"][t, j], a["answer_box_tq23"][t, j])
                for j, q in enumerate(self.rec.queries)]

    def goal(self, t: int) -> str:
        """The goal banner of frame ``t``: the goal as the agent was told it then (a chain reveals
        its goals one by one)."""
        h = self.rec.header
        text = str(h.get("goal") or h.get("instruction") or "")
        for frame, goal in h.get("goal_changes", []):
            if frame <= t:
                text = str(goal)
        return "Goal: " + (text or "(none recorded)")

    def verdict(self) -> tuple[str, bool]:
        """``("SUCCESS", True)``, ``("FAILED", False)`` or the status in capitals (``TIMEOUT``)."""
        h = self.rec.header
        if h.get("success"):
            return "SUCCESS", True
        status = str(h.get("status", "ok"))
        return ("FAILED" if status == "ok" else status.upper()), False

    def _reason(self, t: int, q: int) -> str:
        """Why query ``q`` was last answered "not found" on or before frame ``t`` ("" if unsaid)."""
        reason = ""
        for event in self.rec.header.get("answer_events", []):
            if len(event) >= 4 and event[0] <= t and event[1] == q:
                reason = "" if event[2] else str(event[3])
        return reason

    def _progress(self, t: int) -> list[tuple[str, str]]:
        """How far frame ``t`` is from success: search one line; rearrange one per target and one
        for the other objects."""
        h, out = self.rec.header, []
        if self.goal_distance is not None and math.isfinite(float(self.goal_distance[t])):
            d = float(self.goal_distance[t])
            out.append((f"{d:.2f} m to goal (success within {self.radius:.2f} m)", "ok" if d <= self.radius else "plain"))
        if self.past_line is not None:
            objects = h.get("objects", {})
            names = objects.get("names", [])
            margin = float(h.get("side_margin", SIDE_MARGIN))
            for k, (target, side) in enumerate(zip(objects.get("targets", []), objects.get("sides", []))):
                if k >= self.past_line.shape[1] or not math.isfinite(float(self.past_line[t, k])):
                    continue
                past = float(self.past_line[t, k])
                name = names[target] if target < len(names) else f"target {k + 1}"
                where = f"{_cm(past)} past the line" if past >= 0 else f"{_cm(-past)} on the wrong side of the line"
                out.append((f"{name}: {where} (success: {_cm(margin)} past it, to the {side})",
                            "ok" if past >= margin else "plain"))
            shift = float(self.rec.arrays["distractor_shift_t"][t]) if "distractor_shift_t" in self.rec.arrays else math.nan
            if math.isfinite(shift):
                limit = float(h.get("distractor_tolerance", DISTRACTOR_TOLERANCE))
                out.append((f"other objects moved at most {_cm(shift)} (must stay under {_cm(limit)})",
                            "plain" if shift < limit else "bad"))
        return out

    def _map(self, t: int) -> tuple[str, str]:
        """The map's answer on frame ``t``: where it found each query (search: how far from the
        goal object), or that it did not and why."""
        parts = []
        for j, (q, found, median, _) in enumerate(self.answers(t)):
            if found == 1:
                where = f"'{q}' found at ({median[0]:.2f}, {median[1]:.2f})"
                box = self.goal_box(t)
                if box is not None and np.all(np.isfinite(median[:2])):
                    where += f", {float(box_distance_xy(median[:2], box[0, :2], box[1, :2])):.2f} m from the goal object"
                parts.append(where)
            elif found == 0:
                reason = self._reason(t, j)
                parts.append(f"'{q}' not found" + (f" ({reason})" if reason else ""))
        if parts:
            return "map: " + "; ".join(parts), "answer"
        if self.rec.header.get("map_answers", bool(self.rec.queries)):
            return "map: not asked yet", "dim"
        return "map: the agent keeps none", "dim"

    def _planner(self, t: int) -> tuple[str, str] | None:
        """An instruction agent's last planner call on or before frame ``t``: what it proposed and
        the last line of its reasoning, or its failure (None: no planner, or no call yet)."""
        calls = [c for c in (self.rec.header.get("planner") or {}).get("kept_calls", []) if int(c.get("step", 0)) <= t]
        if not calls:
            return None
        call = calls[-1]
        if call.get("failure"):
            return f"planner failed: {call['failure']}"[:140], "bad"
        why = str(call.get("reasoning", "")).strip().splitlines()
        goals = ", ".join(call.get("goals") or []) or "nothing fits yet, explore"
        return (f"planner (step {call.get('step')}): {goals}" + (f" - {why[-2] if len(why) > 1 else why[0]}" if why else ""))[:140], \
            "answer"

    def _outcome(self) -> tuple[str, str]:
        """The last frame's verdict and why the episode stopped: the harness's stop reason when
        the recording has one, else the error, else whether the agent stopped or ran out of steps."""
        h = self.rec.header
        word, ok = self.verdict()
        if h.get("stop_reason"):
            text = f"{word}: stop reason '{h['stop_reason']}'"
        elif h.get("status", "ok") != "ok":
            error = str(h.get("error") or "").strip().splitlines()
            text = f"{word}: " + (error[0] if error else "the episode did not finish")
        else:
            steps = f"{self.last} step{'' if self.last == 1 else 's'}"
            column = 2 if self.search else 4 if self.rearrange else None  # the action's stop flag
            if column is not None and self.actions.ndim == 2 and len(self.actions) and self.actions.shape[1] > column:
                stopped = float(self.actions[-1, column]) > 0.5
                text = f"{word}: " + ("the agent stopped" if stopped else "the step limit ended it") + f" after {steps}"
            else:
                text = f"{word} after {steps}"
        if not ok and self.goal_distance is not None and math.isfinite(float(self.goal_distance[-1])):
            text += f", {float(self.goal_distance[-1]):.2f} m from the goal"
        return text, "ok" if ok else "bad"

    def styled(self, t: int) -> list[tuple[str, str]]:
        """The lines under the panels on frame ``t`` with their tones (:data:`TONES`): the step;
        how far from success; the map's answer; an instruction agent's planner; on the last frame
        the outcome."""
        h = self.rec.header
        lines = [(f"step {t} of {self.last}   agent {h.get('agent_label', h.get('agent'))}   episode {h.get('episode_id')}",
                  "dim")]
        lines += self._progress(t)
        lines.append(self._map(t))
        planner = self._planner(t)
        if planner is not None:
            lines.append(planner)
        if t == self.last:
            lines.append(self._outcome())
        return lines

    def lines(self, t: int) -> list[str]:
        """All the text of frame ``t``, uncut: the goal banner, then :meth:`styled`'s lines."""
        return [self.goal(t)] + [text for text, _ in self.styled(t)]
