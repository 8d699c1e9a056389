"""Why an episode ended (``extras["stop_reason"]``) and what it was asked (``extras["goal"]``):
the rules on hand-built ends, then short real episodes through the runner."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from agents.registry import AGENTS, AgentSpec, register_agent
from harness.runner.stop_reasons import (
    MOVED_M, NEAR_FACTOR, STOP_REASONS, STUCK_WINDOW, SearchEnd, SearchTrace, box_distances_xy, rearrange_stop_reason,
    search_stop_reason, status_stop_reason,
)
from harness.runner.suites import get_suite
from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode
from sim_envs.scenes.episodes import load_episodes

_SMALL = {"width": 64, "height": 48}


# ---------------------------------------------------------------- the vocabulary and statuses
def test_the_vocabulary_is_the_fixed_nine_words_each_with_a_label():
    assert list(STOP_REASONS) == ["reached", "not_found", "wrong_object", "missed", "planner", "step_limit", "planner_failure",
                                  "timeout", "error"]
    assert all(isinstance(label, str) and label and label != word for word, label in STOP_REASONS.items())


def test_a_timed_out_or_crashed_record_says_so_and_a_finished_one_defers_to_its_task():
    assert status_stop_reason("timeout") == "timeout"
    assert status_stop_reason("failed") == "error"
    assert status_stop_reason("ok") is None
    with pytest.raises(ValueError, match=r"status: expected one of \['failed', 'ok', 'timeout'\], got 'weird'"):
        status_stop_reason("weird")


def test_box_distances_are_horizontal_gaps_to_each_footprint():
    boxes = np.array([[[0, 0, 0], [1, 1, 5]], [[3, 3, 0], [4, 4, 1]]], float)
    assert np.allclose(box_distances_xy([2.0, 0.5], boxes), [1.0, math.hypot(1.0, 2.5)])
    assert np.allclose(box_distances_xy([0.5, 0.5], boxes), [0.0, math.hypot(2.5, 2.5)])
    assert box_distances_xy([0, 0], np.zeros((0, 2, 3))).shape == (0,)
    with pytest.raises(ValueError, match=r"boxes_n23: expected shape \(n, 2, 3\) or \(n, 2, 2\), got \(2, 3\)"):
        box_distances_xy([0, 0], np.zeros((2, 3)))


# ---------------------------------------------------------------- search rules
def _end(**kw) -> SearchEnd:
    """A failed search that stopped 5 m from its goal in the open, having driven a straight line."""
    moving = np.stack([np.linspace(0, 5, STUCK_WINDOW + 1), np.zeros(STUCK_WINDOW + 1)], axis=1)
    base = dict(success=False, stopped=True, success_radius=1.0, goal_distance=5.0, other_distance=math.inf,
                recent_xy=moving, recent_collisions=0)
    return SearchEnd(**{**base, **kw})


_PARKED = np.full((STUCK_WINDOW + 1, 2), 3.0) + np.linspace(0, 0.1, STUCK_WINDOW + 1)[:, None]


@pytest.mark.parametrize("kw, word", [
    ({"success": True, "goal_distance": 0.5}, "reached"),
    ({}, "not_found"),                                                   # stopped in the open, far from everything
    ({"other_distance": 0.6}, "wrong_object"),                           # stopped next to another object
    ({"other_distance": 0.6, "goal_distance": 1.5}, "wrong_object"),     # nearer the other one, within its reach
    ({"goal_distance": 1.5}, "missed"),                                  # near the goal, outside its radius
    ({"goal_distance": NEAR_FACTOR * 1.0}, "missed"),                    # the band's edge counts as near
    ({"goal_distance": NEAR_FACTOR * 1.0 + 0.01}, "not_found"),
    ({"other_distance": 1.01, "goal_distance": 3.0}, "not_found"),       # the other object is out of reach
    ({"stopped": False}, "step_limit"),                                  # still driving when the budget ran out
    ({"stopped": False, "recent_xy": _PARKED}, "planner"),               # parked for the whole window
    ({"stopped": False, "recent_xy": _PARKED, "other_distance": 0.4}, "wrong_object"),  # parked at another object
    ({"stopped": False, "other_distance": 0.4}, "step_limit"),           # passing another object, still going
    ({"stopped": False, "recent_collisions": STUCK_WINDOW // 2 + 1}, "planner"),  # pushing into a wall
    ({"stopped": False, "recent_collisions": STUCK_WINDOW // 2 - 1}, "step_limit"),
    ({"stopped": False, "recent_xy": _PARKED[-5:]}, "step_limit"),       # a short episode is never "parked"
    ({"stopped": False, "recent_xy": _PARKED[-5:], "recent_collisions": 2}, "planner"),  # 2 of its 4 steps collided
])
def test_search_rules(kw, word):
    assert search_stop_reason(_end(**kw)) == word


def test_search_rules_refuse_what_they_cannot_judge():
    with pytest.raises(TypeError, match="end: expected a SearchEnd, got dict"):
        search_stop_reason({"success": True})
    with pytest.raises(ValueError, match=r"success_radius: expected a finite distance > 0, got nan"):
        search_stop_reason(_end(success_radius=float("nan")))


def _objects(*boxes) -> list[dict]:
    return [{"id": f"obj{i}", "category": "thing", "aabb": [[x0, y0, 0.0], [x1, y1, 0.5]]} for i, (x0, y0, x1, y1) in enumerate(boxes)]


def test_the_trace_counts_only_objects_approached_on_the_current_leg():
    """obj0 (the goal) far away, obj1 beside the start (in reach from the outset: not gone for),
    obj2 four metres on: the base drives to obj2 and stops next to it."""
    trace = SearchTrace()
    objects = _objects((9, 9, 9.5, 9.5), (0.5, 0, 0.8, 0.3), (4.5, 0, 4.8, 0.3))
    info = {"scene_graph": {"objects": objects}, "success_distance": 1.0, "collisions": 0, "goal_index": 0, "exploring": False}
    trace.observe({"base_pose": np.array([0.0, 0.0, 0.0])}, info)
    for x in np.arange(0.5, 4.01, 0.5):
        trace.observe({"base_pose": np.array([x, 0.0, 0.0])}, {"collisions": 1, "goal_index": 0})
    end = trace.end({"success": False, "distance_to_goal": 7.0, "goal_object_id": "obj0"}, truncated=False)
    assert end.other_distance == pytest.approx(0.5) and end.success_radius == trace.success_radius == 1.0
    assert end.recent_collisions == 1 and end.recent_xy.shape == (9, 2) and end.recent_xy[-1].tolist() == [4.0, 0.0]
    assert search_stop_reason(end) == "wrong_object"
    # A chain's next goal starts a leg where the base stands: obj2, in reach there, no longer
    # counts; obj1, out of reach there, does (3.2 m away).
    trace.observe({"base_pose": np.array([4.0, 0.0, 0.0])}, {"collisions": 1, "goal_index": 1})
    end = trace.end({"success": False, "distance_to_goal": 7.0, "goal_object_id": "obj0"}, truncated=False)
    assert end.other_distance == pytest.approx(3.2) and search_stop_reason(end) == "not_found"


def test_the_trace_keeps_only_the_last_window():
    trace = SearchTrace()
    trace.observe({"base_pose": np.zeros(3)}, {"scene_graph": {"objects": _objects((9, 9, 10, 10))}, "success_distance": 1.0,
                                               "collisions": 0})
    for k in range(1, 3 * STUCK_WINDOW):
        trace.observe({"base_pose": np.array([0.01 * k, 0, 0])}, {"collisions": k})
    end = trace.end({"success": False, "distance_to_goal": 9.0, "goal_object_id": "obj0"}, truncated=True)
    assert len(end.recent_xy) == STUCK_WINDOW + 1 and end.recent_collisions == STUCK_WINDOW
    assert search_stop_reason(end) == "planner"


# ---------------------------------------------------------------- rearrangement rules
@pytest.mark.parametrize("disp, target, done, word", [
    ([0.0, 0.0, 0.0], [True, False, False], [False], "not_found"),                       # pushed nothing
    ([MOVED_M / 2, 0.001, 0.0], [True, False, False], [False], "not_found"),             # nudges are not pushes
    ([0.15, 0.0, 0.0], [True, False, False], [False], "missed"),                         # the target, not far enough
    ([0.15, 0.2, 0.0], [True, False, False], [False], "wrong_object"),                   # a bystander moved more
    ([0.0, 0.2, 0.0], [True, False, False], [False], "wrong_object"),                    # the target never moved
    ([0.3, 0.08, 0.0], [True, False, False], [True], "missed"),                          # across, but a bystander moved
    ([0.3, 0.0, 0.4], [True, False, True], [True, False], "missed"),                     # one of two targets short
    ([0.3, 0.0, 0.0], [True, False, False], [True], "missed"),
])
def test_rearrange_rules(disp, target, done, word):
    assert rearrange_stop_reason(success=False, displacement_n=disp, target_n=target, targets_done=done) == word


def test_rearrange_success_is_reached_and_lengths_must_agree():
    assert rearrange_stop_reason(success=True, displacement_n=[0.3, 0.0], target_n=[True, False], targets_done=[True]) == "reached"
    with pytest.raises(ValueError, match="expected the same length .one per object., got 3 and 2"):
        rearrange_stop_reason(success=False, displacement_n=[0.3, 0.0, 0.0], target_n=[True, False], targets_done=[False])


# ---------------------------------------------------------------- real episodes
def _episode(suite: str, **changes):
    return dataclasses.replace(load_episodes(get_suite(suite).episodes_file).episodes[0], **changes)


def _job(suite: str, agent: str, episode, agent_kwargs=None) -> EpisodeJob:
    return EpisodeJob(run_id="t", suite=suite, task=get_suite(suite).task, agent=agent, agent_kwargs=agent_kwargs or {},
                      episode=episode, env_kwargs=dict(_SMALL))


class _StopAtOnce:
    """Stops on its first step, in either task (a user's agent that gives up)."""

    privileged = False
    reads_images = False
    reads_scan = False

    def __init__(self, action):
        self.action = np.asarray(action, np.float32)

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return self.action


class _Crash(_StopAtOnce):
    def act(self, observation, info=None):
        raise RuntimeError("the agent fell over")


@pytest.fixture
def user_agents():
    specs = [AgentSpec("test-stop-search", lambda: _StopAtOnce([0, 0, 1]), "object_search", "stops at once (test)"),
             AgentSpec("test-stop-push", lambda: _StopAtOnce([0, 0, 0, 0, 1]), "tabletop_rearrange", "stops at once (test)"),
             AgentSpec("test-crash", lambda: _Crash([0, 0, 1]), "object_search", "raises (test)")]
    for spec in specs:
        register_agent(spec)
    yield
    close_cached_envs()
    for spec in specs:
        AGENTS.pop(spec.name, None)


def test_a_random_walker_out_of_steps_is_step_limit_or_planner():
    episode = _episode("regression-search", max_steps=30)
    try:
        rec = run_episode(_job("regression-search", "random-walker", episode, {"p_stop": 0.0}))
    finally:
        close_cached_envs()
    assert rec["status"] == "ok", rec["error"]
    assert rec["metrics"]["steps"] == 30 and rec["metrics"]["success"] is False
    ex = rec["extras"]
    assert ex["stop_reason"] in ("step_limit", "planner")
    assert ex["goal"] == episode.instruction and ex["success_radius"] == 1.0


def test_a_user_agent_that_gives_up_at_once_is_not_found_and_carries_its_goal(user_agents):
    search = _episode("regression-search")
    rec = run_episode(_job("regression-search", "test-stop-search", search))
    assert rec["status"] == "ok", rec["error"]
    assert rec["metrics"]["steps"] == 1 and rec["metrics"]["distance_to_goal"] > NEAR_FACTOR * 1.0
    assert rec["extras"]["stop_reason"] == "not_found" and rec["extras"]["goal"] == search.instruction
    table = _episode("regression-rearrange")
    rec = run_episode(_job("regression-rearrange", "test-stop-push", table))
    assert rec["status"] == "ok", rec["error"]
    assert rec["extras"]["stop_reason"] == "not_found" and rec["extras"]["goal"] == table.instruction
    assert "success_radius" not in rec["extras"]


def test_a_chain_names_its_goals_in_order(user_agents):
    chain = _episode("chain-v2")
    assert len(chain.goals) >= 2
    rec = run_episode(_job("chain-v2", "test-stop-search", chain))
    assert rec["status"] == "ok", rec["error"]
    assert rec["extras"]["goal"] == " then ".join(g.description for g in chain.goals)
    assert rec["extras"]["goal"].count(" then ") == len(chain.goals) - 1
    assert rec["extras"]["stop_reason"] in STOP_REASONS and rec["extras"]["stop_reason"] != "reached"


def test_an_oracle_that_reaches_its_goal_is_reached():
    try:
        search = run_episode(_job("regression-search", "oracle-searcher", _episode("regression-search")))
        table = run_episode(_job("regression-rearrange", "oracle-pusher", _episode("regression-rearrange")))
    finally:
        close_cached_envs()
    for rec in (search, table):
        assert rec["status"] == "ok", rec["error"]
        assert rec["metrics"]["success"] is True and rec["extras"]["stop_reason"] == "reached"


def test_a_crashed_or_timed_out_episode_says_so(user_agents):
    job = _job("regression-search", "test-crash", _episode("regression-search"))
    rec = run_episode(job)
    assert rec["status"] == "failed" and "the agent fell over" in rec["error"]
    assert rec["extras"] == {"goal": job.episode.instruction, "stop_reason": "error", "sim": "mujoco"}
    assert job.failure_record("timeout", "too slow", 1.0)["extras"]["stop_reason"] == "timeout"
    assert job.failure_record("failed", "worker died", 1.0)["extras"]["stop_reason"] == "error"
