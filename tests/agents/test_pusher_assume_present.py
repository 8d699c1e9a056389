"""The pusher's ``assume_present`` option: an object the instruction names but the score floor
rejects is pushed by its best region when the option is on, and left alone when it is off; with
``name_only_fallback`` too, one whose regions all lose to the generic phrases is pushed by the
region that scores highest for its name alone."""

from __future__ import annotations

import numpy as np
import pytest

from agents.concept_map import ConceptMapper
from agents.pusher import MapPusher, PusherConfig
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region

TABLE_Z = 0.4


def _table_and_mug():
    xs, ys = np.meshgrid(np.arange(-0.5, 0.5, 0.01), np.arange(-0.35, 0.35, 0.01), indexing="ij")
    table = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, TABLE_Z)], axis=1)
    mx, my, mz = np.meshgrid(np.arange(-0.22, -0.16, 0.01), np.arange(-0.03, 0.03, 0.01), np.arange(0.41, 0.5, 0.01), indexing="ij")
    mug = np.stack([mx.ravel(), my.ravel(), mz.ravel()], axis=1)
    return np.concatenate([table, mug]), np.arange(len(table), len(table) + len(mug))


class _UnderTheFloor:
    """A mapper whose map holds a table and a mug; the mug's region is under the score floor."""

    privileged = False

    def __init__(self, loses_to_generics: bool = False) -> None:
        self.loses_to_generics = loses_to_generics
        pts, self.mug = _table_and_mug()
        self.map = type("M", (), {"points": pts})()
        self.asked: list[tuple[str, bool]] = []
        self._answers: dict = {}  # where ConceptMapper.locate_present records what it returns

    locate_present = ConceptMapper.locate_present  # the real fallback chain over this locate

    def reset(self, **_) -> None:
        pass

    def integrate(self, frame, segmentation=None) -> None:
        pass

    def locate(self, text, *, floor=True, contrast=True):
        self.asked.append((text, floor) if contrast else (text, floor, contrast))
        empty = np.zeros(0, np.float32)
        if floor:
            return QueryResult(False, [], empty, empty, empty, reason="the best region scores 0.30, below the encoder's floor 0.35")
        if contrast and self.loses_to_generics:
            return QueryResult(False, [], empty, empty, empty, reason="no region beats the generic phrases")
        pts = self.map.points[self.mug]
        return QueryResult(True, [Region(pts, np.full(len(pts), 0.3, np.float32), self.mug)], empty, empty, empty)


def _observation():
    cam = np.eye(4)
    cam[:3, 3] = (0.0, -1.0, 1.2)
    cam[:3, 2] = (0.0, 0.6, -0.8)
    return {"instruction": "push the mug to the right of the line", "line": np.array([[0.0, -0.35], [0.0, 0.35]]),
            "rgb": np.zeros((4, 4, 3), np.uint8), "depth": np.ones((4, 4), np.float32), "K": np.eye(3), "cam_to_world": cam}


@pytest.mark.parametrize("assume", [False, True])
def test_an_object_under_the_floor_is_pushed_only_when_assumed_present(assume):
    mapper = _UnderTheFloor()
    agent = MapPusher(mapper, PusherConfig(assume_present=assume), use_scan=False)
    action = agent.act(_observation())
    if assume:
        assert action[4] < 0.5 and action[3] > 0  # a push, not a stop
        assert abs(np.cos(action[2]) - 1.0) < 0.2  # towards +x, the right of the line
        assert any("taking its best region" in line for line in agent.log), agent.log
        assert mapper.asked == [("mug", True), ("mug", False)]
    else:
        assert action[4] > 0.5  # stop: nothing to push
        assert any("'mug' not found" in line for line in agent.log), agent.log
        assert mapper.asked == [("mug", True)]


@pytest.mark.parametrize("fallback", [False, True])
def test_a_name_that_loses_to_the_generic_phrases_is_pushed_only_with_the_name_only_fallback(fallback):
    mapper = _UnderTheFloor(loses_to_generics=True)
    agent = MapPusher(mapper, PusherConfig(assume_present=True, name_only_fallback=fallback), use_scan=False)
    action = agent.act(_observation())
    if fallback:
        assert action[4] < 0.5 and action[3] > 0 and abs(np.cos(action[2]) - 1.0) < 0.2
        assert any("scores highest for the name alone" in line for line in agent.log), agent.log
        assert mapper.asked == [("mug", True), ("mug", False), ("mug", False, False)]
    else:
        assert action[4] > 0.5
        assert mapper.asked == [("mug", True), ("mug", False)]
