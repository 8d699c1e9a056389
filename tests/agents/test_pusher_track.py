"""The pusher's ``track_pushed`` option: once an object has been pushed, its next answer is the
returned region nearest where the push should have left it (within the radius), not the one that
scores best; off (0) by default."""

from __future__ import annotations

import numpy as np
import pytest

from agents.pusher import MapPusher, PusherConfig
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region
from tests.agents.test_pusher_assume_present import TABLE_Z, _observation


def _box(x0, y0):
    g = np.meshgrid(np.arange(x0 - 0.03, x0 + 0.03, 0.01), np.arange(y0 - 0.03, y0 + 0.03, 0.01), np.arange(0.41, 0.5, 0.01),
                    indexing="ij")
    return np.stack([a.ravel() for a in g], axis=1)


class _TwoAnswers:
    """A table, a mug at (-0.19, 0) and a decoy at (-0.3, 0.2); the decoy's region scores best."""

    privileged = False

    def __init__(self) -> None:
        xs, ys = np.meshgrid(np.arange(-0.5, 0.5, 0.01), np.arange(-0.35, 0.35, 0.01), indexing="ij")
        table = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, TABLE_Z)], axis=1)
        self.mug_pts, self.decoy_pts = _box(-0.19, 0.0), _box(-0.3, 0.2)
        pts = np.concatenate([table, self.mug_pts, self.decoy_pts])
        self.mug = np.arange(len(table), len(table) + len(self.mug_pts))
        self.decoy = np.arange(self.mug[-1] + 1, len(pts))
        self.map = type("M", (), {"points": pts})()

    def reset(self, **_) -> None:
        pass

    def integrate(self, frame, segmentation=None) -> None:
        pass

    def locate_present(self, text, *, name_only=True, candidates=None):
        empty = np.zeros(0, np.float32)
        pts = self.map.points
        regions = [Region(pts[self.decoy], np.full(len(self.decoy), 0.5, np.float32), self.decoy),
                   Region(pts[self.mug], np.full(len(self.mug), 0.4, np.float32), self.mug)]
        return QueryResult(True, regions, empty, empty, empty)


@pytest.mark.parametrize("track", [0.0, 0.12])
def test_a_pushed_object_is_followed_to_where_the_push_left_it(track):
    agent = MapPusher(_TwoAnswers(), PusherConfig(track_pushed=track), use_scan=False)
    agent._expected["mug"] = np.array([-0.17, 0.02])  # a push of the mug fell short of the line
    action = agent.act(_observation())
    assert action[4] < 0.5 and action[3] > 0  # a push
    start_y = float(action[1])
    if track:
        assert abs(start_y) < 0.06, (action, agent.log)  # behind the mug
        assert any("where the last push should have left it" in line for line in agent.log), agent.log
    else:
        assert abs(start_y - 0.2) < 0.06, (action, agent.log)  # behind the decoy, the best-scoring region
    # every push records where it should leave its object: along the push, past its start
    direction = np.array([np.cos(action[2]), np.sin(action[2])])
    assert float((agent._expected["mug"] - action[:2]) @ direction) > 0


def test_a_region_farther_than_the_radius_is_not_taken():
    agent = MapPusher(_TwoAnswers(), PusherConfig(track_pushed=0.05), use_scan=False)
    agent._expected["mug"] = np.array([-0.05, 0.0])  # 0.14 m from the mug's region
    action = agent.act(_observation())
    assert abs(float(action[1]) - 0.2) < 0.06 and not any("should have left" in line for line in agent.log)


def test_a_negative_radius_is_refused():
    from agents.registry import make_agent

    with pytest.raises(ValueError, match="track_pushed"):
        make_agent("map-pusher", encoder="oracle", track_pushed=-0.1)
