"""The tabletop pusher (paper: push the "goldfish" to the right of the yellow line).

Each step the pusher maps the table from the posed RGB-D frames in its observation (an orbit
scan when the environment provides one, plus the fixed camera's frame), queries the map for every
object the instruction names, takes the **median** of the best region as the object's position
(as the paper does) and the middle of the region's footprint as the point to push through, and
plans a straight push perpendicular to the line towards the instructed side
(:func:`planners.push.plan_push`). Candidate pushes must start on the table (its extent is read
from the map), keep the object on it and not put the finger down on another object; when the
swept corridor would hit other things on the table, pushes tilted by up to 35 degrees that still
cross the line are tried, and a target with no clear corridor waits until the other targets are
done. One push per step; the next step re-maps and re-checks, so an object that did not cross is
pushed again (up to three pushes per object by default). An object counts as done when its
centre is 3.5 cm past the line in the map. It stops when every target is done, or when it has
run out of attempts.

The map-free single-frame variant is the same agent with a non-persistent mapper and no scan:
it sees only the current frame (2.5D).
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass

import numpy as np

from agents.concept_map import ConceptMapper, privileged_labels
from conceptfusion.map.query import connected_regions
from planners.push import plan_push

__all__ = ["MAX_PUSH", "PusherConfig", "MapPusher", "parse_push_instruction", "push_action", "scan_frames"]

_LOG = logging.getLogger(__name__)

MAX_PUSH = 0.5
"""Longest finger travel (m) of one push action."""

_TARGETS = re.compile(
    r"\s*(?:the\s+)?(?P<name>.+?)\s+to\s+the\s+(?P<side>left|right)(?:\s+side)?(?:\s+of\s+the\s+(?:yellow\s+)?line)?(?:\s+and\s+|$)"
)


def parse_push_instruction(text: str) -> list[tuple[str, str]]:
    """``"push the red mug to the right of the line and the blue can to the left of the line"``
    -> ``[("red mug", "right"), ("blue can", "left")]``. ``ValueError`` when nothing parses."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"instruction: expected text such as 'push the red mug to the right of the line', got {text!r}")
    body = re.sub(r"^\s*push\s+", "", text.strip().lower()).rstrip(".").strip()
    out, pos = [], 0
    while pos < len(body):  # targets end at "to the left/right [of the line]"; "and" inside a name stays
        m = _TARGETS.match(body, pos)
        if m is None:
            raise ValueError(f"instruction: cannot read {body[pos:]!r} as '<object> to the left/right of the line' in {text!r}")
        out.append((m["name"].strip(), m["side"]))
        pos = m.end()
    return out


def push_action(start_xy, direction: float, distance: float, stop: bool = False) -> np.ndarray:
    """A TabletopRearrange action ``(start_x, start_y, direction_rad, distance, stop)``, float32 (5,)."""
    return np.array([start_xy[0], start_xy[1], direction, distance, 1.0 if stop else 0.0], np.float32)


def scan_frames(observation) -> list[dict]:
    """The posed frames in an observation: the scan's (``scan_rgb`` ...) then the current one."""
    frames = []
    if "scan_rgb" in observation:
        for i in range(len(observation["scan_rgb"])):
            frames.append({k: observation[f"scan_{k}"][i] for k in ("rgb", "depth", "K", "cam_to_world")})
    frames.append({k: observation[k] for k in ("rgb", "depth", "K", "cam_to_world")})
    return frames


@dataclass(frozen=True)
class PusherConfig:
    """Settings of :class:`MapPusher`."""

    margin: float = 0.07
    """Push until the object's centre is this far past the line (success needs 2 cm)."""
    done_margin: float = 0.035
    """An object whose centre is this far past the line in the map needs no more pushing."""
    approach_clearance: float = 0.04
    """The fingertip starts this far behind the object's back."""
    attempts_per_object: int = 3
    """Pushes per object (the first plus retries)."""
    finger_radius: float = 0.015
    """Radius of the environment's fingertip (m)."""
    corridor_half_width: float = 0.03
    """Extra half-width (m) of the swept corridor checked for other objects."""
    tilts_deg: tuple[float, ...] = (0.0, 20.0, -20.0, 35.0, -35.0)
    """Push directions tried, relative to the line's normal."""
    assume_present: bool = True
    """An instruction names objects that are on the table: when the encoder's score floor
    rejects every region of one, push its best region anyway (it must still beat the generic
    phrases, :meth:`~agents.concept_map.ConceptMapper.locate` with ``floor=False``). False:
    an object under the floor is not pushed. Chosen on development episodes; see
    docs/measurement-history.md."""
    identify: bool = True
    """With ``assume_present`` and a mapper whose encoder records the names it was trained on
    (:attr:`~agents.concept_map.ConceptMapper.vocabulary`; the v2 tower's train categories): a
    named object the score floor rejects everywhere is the thing on the table whose concept
    vectors look most like its name rather than like any trained name
    (:meth:`~agents.concept_map.ConceptMapper.identify` over the connected groups of map points
    above the table), instead of its best region under the floor (or the name-only region). A
    category the tower never saw scores low for its own name, but the table's other objects
    score higher still for the names they are. Without a vocabulary (the oracles, CLIP, the v1
    tower) nothing changes. Only objects under the floor are answered this way: the query's own
    region separates objects that touch, a group of points does not. Chosen on development
    episodes; see docs/measurement-history.md."""
    name_only_fallback: bool = True
    """With ``assume_present``: when no region of a named object beats the generic phrases
    either, push the region that scores highest for its name alone
    (:meth:`~agents.concept_map.ConceptMapper.locate` with ``contrast=False``). A category the
    encoder never learned scores below "object" nearly everywhere, yet its own points still
    score highest for its name (``cfharness develop in-scene`` measures both). False: such an
    object is not pushed. Chosen on development episodes; see docs/measurement-history.md."""


class MapPusher:
    """Map-equipped (or single-frame) tabletop pushing agent; see the module docstring.

    Args:
        mapper: the ConceptFusion mapper; ``MapperConfig(persistent=False)`` for the 2.5D baseline.
        config: see :class:`PusherConfig`.
        use_scan: fuse the observation's orbit scan (False: only the current frame).
    """

    def __init__(self, mapper: ConceptMapper, config: PusherConfig = PusherConfig(), *, use_scan: bool = True) -> None:
        self.mapper, self.config, self.use_scan = mapper, config, bool(use_scan)
        self.reads_scan = self.use_scan
        """Whether :meth:`act` reads the observation's orbit scan (``scan_*``); runners leave the
        scan out for agents that do not."""
        self.privileged = mapper.privileged
        self.reset()

    def reset(self, *, seed: int | None = None) -> None:
        self._targets: list[tuple[str, str]] | None = None
        self._attempts: dict[str, int] = {}
        self.log: list[str] = []

    def _map(self, observation, info) -> None:
        self.mapper.reset(**privileged_labels(self.mapper, info))
        frames = scan_frames(observation) if self.use_scan else scan_frames({k: observation[k] for k in ("rgb", "depth", "K", "cam_to_world")})
        segs = None
        if self.privileged and info is not None:
            segs = list(info.get("scan_segmentation", [])) if self.use_scan and "scan_rgb" in observation else []
            segs.append(info.get("segmentation"))
        for i, frame in enumerate(frames):
            self.mapper.integrate(frame, segmentation=segs[i] if segs else None)

    def _table_z(self) -> float:
        z = self.mapper.map.points[:, 2]
        z = z[z > 0.1]
        if len(z) == 0:
            return 0.0
        hist, edges = np.histogram(z, bins=np.arange(z.min(), z.max() + 0.01, 0.005))
        return float(edges[int(np.argmax(hist))] + 0.0025)

    def _table_objects(self, above_n: np.ndarray) -> list:
        """The things on the table: connected groups of the map's points above it that have
        concept vectors (``identify``'s candidates), as regions of the map.

        Shape: ``above_n`` (N,) bool over the map's points -> list of Region."""
        m = self.mapper
        pts = m.map.points
        return connected_regions(pts, above_n & m.described_n, np.zeros(len(pts), np.float32),
                                 voxel_size=m.config.voxel_size, min_points=m.config.min_points)

    def _corridor_clear(self, start, direction, length, half_width, others_xy) -> bool:
        if len(others_xy) == 0:
            return True
        d = np.array([math.cos(direction), math.sin(direction)])
        rel = others_xy - start
        along = rel @ d
        across = np.abs(rel @ np.array([-d[1], d[0]]))
        return not np.any((along > -0.02) & (along < length) & (across < half_width))

    def _table_xy(self, table_z: float) -> np.ndarray:
        """(2, 2) lower and upper corner of the table top, from the map points at its height."""
        pts = self.mapper.map.points
        top = pts[np.abs(pts[:, 2] - table_z) < 0.01][:, :2]
        if len(top) < 20:
            return np.array([[-np.inf, -np.inf], [np.inf, np.inf]])
        return np.percentile(top, [0.5, 99.5], axis=0)

    def act(self, observation, info: dict | None = None) -> np.ndarray:
        if self._targets is None:
            self._targets = parse_push_instruction(str(observation["instruction"]))
        self._map(observation, info)
        line = np.asarray(observation["line"], np.float64).reshape(2, 2)
        line_dir = line[1] - line[0]
        view = np.asarray(observation["cam_to_world"], np.float64)[:3, 2]
        table_z = self._table_z()
        table_lo, table_hi = self._table_xy(table_z)
        pts = self.mapper.map.points
        above = pts[:, 2] > table_z + 0.012
        c = self.config

        def on_table(xy, inset: float) -> bool:
            return bool(np.all(xy >= table_lo + inset) and np.all(xy <= table_hi - inset))

        fallbacks = []  # (name, side, push) with a blocked corridor: tried after every clear push
        objects = None  # the table's objects (identify's candidates), grouped once per step when needed
        for name, side in self._targets:
            if c.assume_present:
                if objects is None and c.identify and getattr(self.mapper, "vocabulary", ()):
                    objects = self._table_objects(above)
                res = self.mapper.locate_present(name, name_only=c.name_only_fallback, candidates=objects)
                presumed, passed = res.extras.get("presumed"), res.extras.get("passed_over", [])
                if presumed == "identified":
                    margins = res.extras["margins"]
                    self.log.append(f"'{name}' under the floor ({passed[0]}); the instruction names it: of {len(margins)} things on "
                                    f"the table, taking the one most like it against the encoder's vocabulary (margin {margins[0]:+.2f}"
                                    + (f", next {margins[1]:+.2f})" if len(margins) > 1 else ")"))
                elif presumed == "under_floor":
                    self.log.append(f"'{name}' under the floor ({passed[0]}); the instruction names it: taking its best region")
                elif presumed == "name_only":
                    self.log.append(f"'{name}' loses to the generic phrases ({passed[-1]}); the instruction names it: "
                                    "taking the region that scores highest for the name alone")
            else:
                res = self.mapper.locate(name)
            if not res.found:
                self.log.append(f"'{name}' not found: {res.reason}")
                continue
            region = res.best
            obj_pts = region.points_n3[region.points_n3[:, 2] > table_z + 0.005]
            if len(obj_pts) < 5:
                obj_pts = region.points_n3
            centre = region.median
            # The push goes through the middle of the object's footprint: a finger that hits a
            # round object off its centre line rolls it sideways (the median of the visible
            # surface can sit a centimetre off it).
            lo, hi = np.percentile(obj_pts[:, :2], [5, 95], axis=0)
            centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, centre[2]])
            plan = plan_push(centre, line[0], line_dir, side, view_dir=view, footprint_xy=obj_pts[:, :2], margin=c.margin, approach_clearance=c.approach_clearance)
            if plan.signed_distance >= c.done_margin:
                continue
            if self._attempts.get(name, 0) >= c.attempts_per_object:
                self.log.append(f"'{name}' still not past the line after {c.attempts_per_object} pushes: giving up on it")
                continue
            # Points of other things on the table (not this region) block a corridor.
            mine = np.zeros(len(pts), bool)
            mine[region.indices_n] = True
            near = np.linalg.norm(pts[:, :2] - centre[:2], axis=1) < 0.6
            others = pts[above & ~mine & near][:, :2]
            extent = np.ptp(obj_pts[:, :2], axis=0).max() / 2 if len(obj_pts) > 1 else 0.03
            normal = plan.push_direction[:2]
            base = math.atan2(normal[1], normal[0])
            choice = fallback = None
            for tilt in c.tilts_deg:
                ang = base + math.radians(tilt)
                d = np.array([math.cos(ang), math.sin(ang)])
                cos_t = max(float(d @ normal), 0.3)
                back = float(np.max(-(obj_pts[:, :2] - centre[:2]) @ d)) if len(obj_pts) else extent
                start = centre[:2] - (back + c.finger_radius + c.approach_clearance) * d
                travel = plan.push_distance / cos_t
                dist = c.approach_clearance + travel
                if not (on_table(start, 0.005) and on_table(centre[:2] + travel * d, extent * 0.5)):
                    continue  # the finger must come down on the table and the object stay on it
                if len(others) and np.min(np.linalg.norm(others - start, axis=1)) < c.finger_radius + 0.01:
                    continue  # the finger would come down on another object
                push = (start, ang, dist)
                if fallback is None:
                    fallback = push
                if self._corridor_clear(start, ang, dist + 2 * back, extent + c.corridor_half_width, others):
                    choice = push
                    break
            if choice is not None:
                return self._push(name, side, choice)
            if fallback is not None:
                fallbacks.append((name, side, fallback))
            else:
                self.log.append(f"'{name}': no push keeps the finger and the object on the table")
        if fallbacks:
            name, side, push = fallbacks[0]
            self.log.append(f"'{name}': no clear corridor, pushing anyway")
            return self._push(name, side, push)
        return push_action((0.0, 0.0), 0.0, 0.0, stop=True)

    def _push(self, name: str, side: str, push: tuple) -> np.ndarray:
        start, ang, dist = push
        self._attempts[name] = self._attempts.get(name, 0) + 1
        self.log.append(f"push '{name}' to the {side}: start {np.round(start, 3).tolist()}, dir {math.degrees(ang):.0f} deg, {dist:.2f} m")
        return push_action(start, ang, min(dist, MAX_PUSH))
