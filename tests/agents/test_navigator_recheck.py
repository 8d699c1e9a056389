"""The navigator's look-again rule (``recheck_faded``): a goal that fades as the base arrives is
looked at once more from there; a close look that does not confirm it rejects the sighting."""

from __future__ import annotations

import numpy as np
import pytest

from agents.navigator import MapNavigator, NavigatorConfig
from conceptfusion.map.query import QueryResult
from conceptfusion.map.regions import Region
from tests.agents.test_navigator_approach import GOAL, _drive, _world

DECOY = np.array([3.0, 0.0])
"""Where the fading sighting is (the approach tests' goal position)."""


def _answer(*centres) -> QueryResult:
    regions = [Region(np.array([[x, y, 0.5]]), np.ones(1, np.float32)) for x, y in centres]
    empty = np.zeros(0, np.float32)
    return QueryResult(bool(regions), regions, empty, empty, empty, reason="" if regions else "below the floor")


class _Mapper:
    """A region at ``DECOY`` that drops under the floor once the base is within ``fade`` m of it:
    for good (``back_after`` None) or for that many queries, then stands out again. ``other``:
    a second, weaker region elsewhere, found throughout."""

    privileged = False

    def __init__(self, fade: float = 1.2, back_after: int | None = None, other=None) -> None:
        self.map = type("M", (), {"points": _world(0.3)})()
        self.fade, self.back_after, self.other = fade, back_after, other
        self.pose, self.faded_queries = None, 0

    def reset(self, names=None) -> None:
        pass

    def integrate(self, observation, segmentation=None) -> None:
        self.pose = np.asarray(observation["base_pose"], np.float64)

    def locate(self, text):
        extra = [self.other] if self.other is not None else []
        if self.pose is not None and np.linalg.norm(self.pose[:2] - DECOY) < self.fade:
            self.faded_queries += 1
            if self.back_after is None or self.faded_queries <= self.back_after:
                return _answer(*extra)
        return _answer(DECOY, *extra)


def test_a_sighting_a_close_look_does_not_confirm_is_rejected():
    # without the late presumption, which would take a guess once nothing is left to explore
    agent = MapNavigator(_Mapper(), NavigatorConfig(recheck_faded=True, presume_after=0))
    _, stopped = _drive(agent, steps=120)
    assert any("looking again" in line for line in agent.log), agent.log
    assert any("does not confirm" in line for line in agent.log), agent.log
    assert not any("within reach" in line for line in agent.log), agent.log
    assert len(agent._rejected) == 1 and np.linalg.norm(agent._rejected[0] - DECOY) < 0.1
    # once rejected, the region at the sighting no longer counts as found
    agent.mapper.pose = None  # far away again: the mapper reports the decoy as standing out
    assert not agent._locate().found


def test_a_goal_found_again_by_the_close_look_is_stopped_at():
    agent = MapNavigator(_Mapper(back_after=1), NavigatorConfig(recheck_faded=True))
    pose, stopped = _drive(agent)
    assert stopped and any("looking again" in line for line in agent.log), agent.log
    assert not agent._rejected
    assert float(np.linalg.norm(pose[:2] - GOAL)) <= agent.config.standoff + agent.config.goal_tolerance


def test_after_a_rejection_the_next_region_is_the_goal():
    agent = MapNavigator(_Mapper(other=(1.0, 1.5)), NavigatorConfig(recheck_faded=True))
    agent.mapper.other = None  # the second region appears only after the rejection
    agent.act({"base_pose": np.array([0.5, 0.0, 0.0]), "goal": "the basket"})
    agent._rejected.append(DECOY.copy())
    agent.mapper.other = (1.0, 1.5)
    found = agent._locate()
    assert found.found and len(found.regions) == 1
    np.testing.assert_allclose(found.best.points_n3[0, :2], (1.0, 1.5))


def test_off_by_default_it_stops_where_the_goal_faded():
    agent = MapNavigator(_Mapper(), NavigatorConfig())
    _, stopped = _drive(agent)
    assert stopped and any("no longer stands out, but it was seen" in line for line in agent.log), agent.log


@pytest.mark.parametrize("kwargs", [{"recheck_faded": 1}, {"reject_radius": 0.0}, {"reject_radius": float("inf")}])
def test_bad_recheck_settings(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        NavigatorConfig(**kwargs)
