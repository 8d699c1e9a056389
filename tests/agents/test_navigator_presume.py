"""The navigator's late presumption (``presume_after``): from that step on, a goal the score floor
rejects everywhere is presumed present and its best guess is driven to."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.navigator import MapNavigator, NavigatorConfig
from tests.agents.test_navigator_approach import GOAL, _drive, _world
from tests.agents.test_navigator_faded_goal import _answer


class _UnsureMapper:
    """Nothing passes the floor; :meth:`locate_present` finds the goal's region by its name alone."""

    privileged = False

    def __init__(self) -> None:
        self.map = type("M", (), {"points": _world(0.3)})()
        self.presence_queries = 0

    def reset(self, names=None) -> None:
        pass

    def integrate(self, observation, segmentation=None) -> None:
        pass

    def locate(self, text):
        return _answer()

    def locate_present(self, text, name_only=True):
        self.presence_queries += 1
        found = _answer(GOAL)
        return dataclasses.replace(found, extras={"presumed": "name_only", "passed_over": ["below the floor", "loses"]})


def test_from_the_given_step_on_the_best_guess_is_driven_to():
    agent = MapNavigator(_UnsureMapper(), NavigatorConfig(presume_after=6))
    pose, stopped = _drive(agent, steps=200)
    assert stopped and float(np.linalg.norm(pose[:2] - GOAL)) <= agent.config.standoff + agent.config.goal_tolerance
    presumed = [line for line in agent.log if "presumed present (name_only)" in line]
    assert len(presumed) == 1 and int(presumed[0].split(":")[0].split()[1]) >= 6, agent.log


def test_with_nothing_left_to_explore_the_guess_comes_before_the_step():
    agent = MapNavigator(_UnsureMapper(), NavigatorConfig(presume_after=1000))
    pose, stopped = _drive(agent, steps=200)
    assert stopped and float(np.linalg.norm(pose[:2] - GOAL)) <= agent.config.standoff + agent.config.goal_tolerance
    assert any("no frontier left: presuming the goal present" in line for line in agent.log), agent.log
    assert agent._steps < 1000


def test_switched_off_the_floor_has_the_last_word():
    mapper = _UnsureMapper()
    agent = MapNavigator(mapper, NavigatorConfig(presume_after=0))
    _, stopped = _drive(agent, steps=200)
    # the fake apartment is explored within a few dozen steps and the search gives up there
    assert stopped and agent.log[-1].endswith("no goal and no frontier left: stop") and mapper.presence_queries == 0
    assert not any("presum" in line or "within reach" in line for line in agent.log)


@pytest.mark.parametrize("value", [-1, 1.5, True])
def test_bad_presume_after(value):
    with pytest.raises(ValueError, match="presume_after"):
        NavigatorConfig(presume_after=value)


def test_the_builtin_default_is_the_configs():
    import inspect

    from agents.registry import AGENTS

    spec = AGENTS["map-navigator"]
    assert (spec.kwargs["presume_after"].default == inspect.signature(spec.factory).parameters["presume_after"].default
            == NavigatorConfig().presume_after > 0)


def test_a_privileged_mapper_never_presumes():
    mapper = _UnsureMapper()
    mapper.privileged = True  # ground truth: a goal it does not find has not been seen
    agent = MapNavigator(mapper, NavigatorConfig(presume_after=1))
    _, stopped = _drive(agent, steps=200)
    assert stopped and mapper.presence_queries == 0 and agent.log[-1].endswith("no goal and no frontier left: stop")
