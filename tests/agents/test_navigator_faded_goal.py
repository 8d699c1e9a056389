"""A goal whose region fades under the score floor just as the base arrives: the navigator stops
there, trusting the earlier sighting (looking again first was tried and left out, see
docs/measurement-history.md)."""

from __future__ import annotations

import numpy as np

from agents.navigator import MapNavigator, NavigatorConfig
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region
from tests.agents.test_navigator_approach import _drive, _world

DECOY = np.array([3.0, 0.0])
"""Where the fading sighting is (the approach tests' goal position)."""


def _answer(*centres) -> QueryResult:
    regions = [Region(np.array([[x, y, 0.5]]), np.ones(1, np.float32)) for x, y in centres]
    empty = np.zeros(0, np.float32)
    return QueryResult(bool(regions), regions, empty, empty, empty, reason="" if regions else "below the floor")


class _Mapper:
    """A region at ``DECOY`` that drops under the floor for good once the base is within
    ``fade`` m of it."""

    privileged = False

    def __init__(self, fade: float = 1.2) -> None:
        self.map = type("M", (), {"points": _world(0.3)})()
        self.fade, self.pose = fade, None

    def reset(self, names=None) -> None:
        pass

    def integrate(self, observation, segmentation=None) -> None:
        self.pose = np.asarray(observation["base_pose"], np.float64)

    def locate(self, text):
        if self.pose is not None and np.linalg.norm(self.pose[:2] - DECOY) < self.fade:
            return _answer()
        return _answer(DECOY)


def test_it_stops_where_the_goal_faded():
    agent = MapNavigator(_Mapper(), NavigatorConfig())
    pose, stopped = _drive(agent)
    assert stopped and any("no longer stands out, but it was seen" in line for line in agent.log), agent.log
    assert float(np.linalg.norm(pose[:2] - DECOY)) < agent.mapper.fade
