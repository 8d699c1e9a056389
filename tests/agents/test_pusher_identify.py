"""The pusher's ``identify`` option: when the score floor rejects a named object everywhere and
the encoder records the names it was trained on, the object pushed is the thing on the table
that :meth:`~agents.concept_map.ConceptMapper.identify` ranks first among the connected groups of
map points above the table; without a vocabulary, or with the option off, the query's best
region under the floor is pushed as before; a floored answer is never second-guessed."""

from __future__ import annotations

import numpy as np
import pytest

from agents.concept_map import ConceptMapper, MapperConfig
from agents.pusher import MapPusher, PusherConfig
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region
from tests.agents.test_pusher_assume_present import TABLE_Z, _observation


def _box(x0, y0):
    """Points of a 6 cm x 6 cm x 9 cm box standing on the table at (x0, y0)."""
    g = np.meshgrid(np.arange(x0 - 0.03, x0 + 0.03, 0.01), np.arange(y0 - 0.03, y0 + 0.03, 0.01), np.arange(0.41, 0.5, 0.01),
                    indexing="ij")
    return np.stack([a.ravel() for a in g], axis=1)


class _Table:
    """A table with a mug at (-0.19, 0) and a toy at (-0.3, 0.2). The query's regions (floored
    when ``floored``, else only under the floor) are the mug's; ``identify`` ranks the toy first."""

    privileged = False

    def __init__(self, vocabulary=("bowl", "cup"), floored=False, things_on_table=True) -> None:
        xs, ys = np.meshgrid(np.arange(-0.5, 0.5, 0.01), np.arange(-0.35, 0.35, 0.01), indexing="ij")
        table = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, TABLE_Z)], axis=1)
        mug, toy = _box(-0.19, 0.0), _box(-0.3, 0.2)
        pts = np.concatenate([table, mug, toy])
        self.mug = np.arange(len(table), len(table) + len(mug))
        self.toy = np.arange(self.mug[-1] + 1, len(pts))
        self.map = type("M", (), {"points": pts, "has_feature": np.arange(len(pts)) < (len(pts) if things_on_table else len(table))})()
        self.config = MapperConfig()
        self.vocabulary, self.floored = tuple(vocabulary), floored
        self.asked: list = []
        self.candidates: list[Region] | None = None
        self._answers: dict = {}

    locate_present = ConceptMapper.locate_present

    @property
    def described_n(self):
        return self.map.has_feature

    def reset(self, **_) -> None:
        pass

    def integrate(self, frame, segmentation=None) -> None:
        pass

    def locate(self, text, *, floor=True, contrast=True):
        self.asked.append(("locate", floor, contrast))
        empty = np.zeros(0, np.float32)
        if floor and not self.floored:
            return QueryResult(False, [], empty, empty, empty, reason="the best region scores 0.30, below the encoder's floor 0.35")
        return QueryResult(True, [Region(self.map.points[self.mug], np.full(len(self.mug), 0.3, np.float32), self.mug)], empty, empty, empty)

    def identify(self, text, candidates):
        self.asked.append(("identify",))
        self.candidates = list(candidates)
        toy_first = sorted(candidates, key=lambda r: -len(np.intersect1d(r.indices_n, self.toy)))
        empty = np.zeros(0, np.float32)
        return QueryResult(True, toy_first, empty, empty, empty, extras={"identified": "vocabulary", "margins": [0.1, -0.2]})


def _start_y(action) -> float:
    assert action[4] < 0.5 and action[3] > 0, action  # a push, not a stop
    return float(action[1])


def test_an_object_under_the_floor_is_the_table_object_identify_ranks_first():
    mapper = _Table()
    agent = MapPusher(mapper, PusherConfig(), use_scan=False)
    assert abs(_start_y(agent.act(_observation())) - 0.2) < 0.06, agent.log  # behind the toy
    assert mapper.asked == [("locate", True, True), ("identify",)]
    # the candidates are the two things standing on the table: their points above its surface
    groups = sorted(mapper.candidates, key=lambda r: r.indices_n.min())
    above = mapper.map.points[:, 2] > TABLE_Z + 0.012
    assert len(groups) == 2
    assert np.array_equal(np.sort(groups[0].indices_n), mapper.mug[above[mapper.mug]])
    assert np.array_equal(np.sort(groups[1].indices_n), mapper.toy[above[mapper.toy]])
    assert any("against the encoder's vocabulary" in line and "under the floor" in line for line in agent.log), agent.log


@pytest.mark.parametrize("case", ["option off", "no vocabulary"])
def test_without_the_option_or_a_vocabulary_the_region_under_the_floor_is_pushed(case):
    mapper = _Table(vocabulary=() if case == "no vocabulary" else ("bowl",))
    agent = MapPusher(mapper, PusherConfig(identify=case != "option off"), use_scan=False)
    assert abs(_start_y(agent.act(_observation()))) < 0.06, agent.log  # behind the mug
    assert ("identify",) not in mapper.asked and mapper.asked[:2] == [("locate", True, True), ("locate", False, True)]


def test_with_nothing_on_the_table_to_choose_from_the_region_under_the_floor_is_pushed():
    mapper = _Table(things_on_table=False)  # the objects' points have no concept vectors: no candidates
    agent = MapPusher(mapper, PusherConfig(), use_scan=False)
    assert abs(_start_y(agent.act(_observation()))) < 0.06, agent.log  # behind the mug, its region under the floor
    assert ("identify",) not in mapper.asked
    assert mapper.asked[-2:] == [("locate", True, True), ("locate", False, True)]
    assert any("taking its best region" in line for line in agent.log), agent.log


def test_a_floored_answer_is_pushed_without_identify():
    mapper = _Table(floored=True)
    agent = MapPusher(mapper, PusherConfig(), use_scan=False)
    assert abs(_start_y(agent.act(_observation()))) < 0.06, agent.log
    assert mapper.asked == [("locate", True, True)]


def test_the_option_reaches_both_pushers(monkeypatch):
    from agents.registry import make_agent

    monkeypatch.setattr("agents.builtin.make_mapper", lambda *a, **k: _Table())  # no encoder to load
    for name in ("map-pusher", "frame-pusher"):
        assert make_agent(name, encoder="oracle").config.identify
        assert not make_agent(name, encoder="oracle", identify=False).config.identify
