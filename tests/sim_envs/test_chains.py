"""Multi-goal search: chains revealed one at a time, scored per position, refused when malformed."""

import dataclasses
import json
import shutil

import gymnasium as gym
import numpy as np
import pytest

import sim_envs  # noqa: F401
from agents.navigator import MapNavigator, NavigatorConfig
from agents.oracle_search import OracleSearchAgent
from harness.runner.suites import get_suite, suite_episodes
from harness.runner.tasks import EpisodeJob, run_episode
from sim_envs.scenes.chain_episodes import THEN, check_chains_reachable
from sim_envs.scenes.episodes import SCENES_ROOT, EpisodeFormatError, load_episodes
from sim_envs.scenes.sealed import SEALED_FOLDER

CAL = SCENES_ROOT / "calibration-v2" / "chain-episodes-v2.jsonl"
SEALED = SEALED_FOLDER / "chain-episodes-v2.jsonl"


def _env(ep):
    return gym.make("cf/ObjectSearch-v0", episodes=[ep], width=32, height=24).unwrapped


def test_shipped_chains_have_two_to_four_goals_in_different_rooms_and_a_budget_per_goal():
    from sim_envs.scenes.episodes import resolve_scene
    from sim_envs.scenes.search_episodes import room_of

    for path in (CAL, SEALED):
        eps = load_episodes(path).episodes
        assert len(eps) == 30 and sorted({len(e.goals) for e in eps}) == [2, 3, 4]
        for ep in eps:
            assert ep.max_steps == 250 * len(ep.goals) and ep.instruction == THEN.join(g.description for g in ep.goals)
            scene = resolve_scene(ep.scene, ep.scene_seed)
            rooms = [room_of(scene, scene.object(g.object_id).position[:2]) for g in ep.goals]
            assert all(a != b for a, b in zip(rooms, rooms[1:])), ep.episode_id
    assert get_suite("chain-v2").episodes_file == SEALED and len(suite_episodes(get_suite("chain-v2"))) == 30


def test_a_stop_at_the_goal_reveals_the_next_and_a_stop_elsewhere_ends_the_chain():
    ep = load_episodes(CAL).episodes[1]  # three goals
    env = _env(ep)
    obs, info = env.reset(seed=0, options={"episode": ep})
    assert obs["goal"] == ep.goals[0].description and info["chain_length"] == 3 and info["goal_index"] == 0
    agent = OracleSearchAgent()
    agent.reset()
    rewards, goals_seen = [], [obs["goal"]]
    done = False
    while not done:
        obs, reward, term, trunc, info = env.step(agent.act(obs, info))
        done = term or trunc
        rewards.append(reward)
        if reward and not done:  # reached and revealed the next goal, episode going on
            assert info["goal_reached"] and not info["success"]
            goals_seen.append(obs["goal"])
    assert info["success"] and info["goals_reached"] == 3 and sum(rewards) == 3
    assert goals_seen == [g.description for g in ep.goals]
    assert 0 < info["spl"] <= 1 and info["shortest_path_length"] > 0
    # a stop far from the first goal ends the chain at once, nothing reached
    obs, info = env.reset(seed=0, options={"episode": ep})
    obs, reward, term, trunc, info = env.step(np.array([0.0, 0.0, 1.0]))
    assert term and not info["success"] and info["goals_reached"] == 0 and reward == 0.0
    env.close()


def test_oracle_solves_chains_and_records_carry_the_positions():
    eps = load_episodes(SEALED).episodes[:6]
    for ep in eps:
        rec = run_episode(EpisodeJob("t", "chain-v2", "object_search", "oracle-searcher", {}, ep, 0, {"width": 32, "height": 24}))
        assert rec["status"] == "ok", rec.get("error")
        m = rec["metrics"]
        assert m["success"] and m["goals_reached"] == m["chain_length"] == len(ep.goals)
        assert [m[f"reached_{k}"] for k in range(1, len(ep.goals) + 1)] == [True] * len(ep.goals)
        assert f"reached_{len(ep.goals) + 1}" not in m


def test_a_chain_goal_without_a_description_is_refused():
    ep = load_episodes(CAL).episodes[0]
    bad = dataclasses.replace(ep, goals=(ep.goals[0], dataclasses.replace(ep.goals[1], description=None)))
    with pytest.raises(ValueError, match=r"goals\[1\]\.description: a chain's goals are shown one at a time"):
        _env(bad).reset(seed=0, options={"episode": bad})


def _copy(tmp_path, change_line=None, scene_change=None):
    """The calibration chains in a scenes folder of their own, line 2 changed by ``change_line``."""
    root = tmp_path / "scenes"
    (root / "calibration-v2").mkdir(parents=True)
    lines = CAL.read_text().splitlines()
    first = json.loads(lines[1])
    if change_line:
        change_line(first)
    lines = [lines[0], json.dumps(first)]
    (root / "calibration-v2" / CAL.name).write_text("\n".join(lines) + "\n")
    scene = json.loads((SCENES_ROOT / first["scene"]).read_text())
    if scene_change:
        scene_change(scene, first)
    (root / first["scene"]).write_text(json.dumps(scene))
    return root, root / "calibration-v2" / CAL.name


def test_a_repeated_or_missing_goal_is_refused_naming_file_line_and_field(tmp_path):
    root, path = _copy(tmp_path, lambda ep: ep["goals"].append(dict(ep["goals"][0])))
    with pytest.raises(EpisodeFormatError, match=r"chain-episodes-v2.jsonl:line 2: goals\[2\]\.object_id .* repeats goals\[0\]"):
        load_episodes(path, scenes_root=root)
    root, path = _copy(tmp_path / "b", lambda ep: ep.update(goals=[]))
    with pytest.raises(EpisodeFormatError, match=r"line 2: 'goals' expected a non-empty list"):
        load_episodes(path, scenes_root=root)


def test_an_unreachable_goal_is_refused_before_any_episode_runs(tmp_path):
    def close_doors(scene, ep):
        for wall in scene["walls"]:
            wall["doors"] = []  # every room sealed off: the goals in other rooms than the start's are out of reach

    root, path = _copy(tmp_path, scene_change=close_doors)
    eps = load_episodes(path, scenes_root=root).episodes
    with pytest.raises(EpisodeFormatError, match=r"chain-episodes-v2.jsonl:line 2: episode 'chain-v2-cal-0000': goals\[\d\]\.object_id "
                                                 r"'obj\d+' cannot be reached from the start pose"):
        check_chains_reachable(eps, where=str(path), scenes_root=root)
    shutil.rmtree(root)


class _Mapper:
    privileged = False

    def __init__(self):
        self.map = type("M", (), {"points": np.zeros((0, 3))})()

    def reset(self, **_):
        self.resets = getattr(self, "resets", 0) + 1

    def integrate(self, observation, segmentation=None):
        pass


def test_the_navigator_keeps_its_map_and_starts_the_goals_own_state_on_a_new_goal():
    mapper = _Mapper()
    nav = MapNavigator(mapper, NavigatorConfig())
    nav._started, nav._goal, nav._steps = True, "the fork", 120
    nav._seen, nav._presumed, nav._exhausted, nav._phase = np.zeros((3, 2)), "under_floor", True, "follow"
    nav._next_goal("the toaster")
    assert nav._goal == "the toaster" and nav._goal_start == 120 and nav._phase == "plan"
    assert nav._seen is None and nav._presumed is None and not nav._exhausted
    assert "next goal 'the toaster' (after 'the fork')" in nav.log[-1]
    assert not hasattr(mapper, "resets")  # the map is kept
    assert not nav._looking_again  # the map navigator's map remembers what it saw


def test_the_twin_looks_again_for_a_later_goal():
    nav = MapNavigator(_Mapper(), NavigatorConfig(look_again=True))
    nav._started, nav._goal, nav._steps, nav._visited = True, "the fork", 80, [np.zeros(2)]
    nav._close_keys = np.arange(5, dtype=np.int64)
    nav._next_goal("the toaster")
    assert nav._phase == "look" and nav._turned == 0.0 and nav._looking_again
    assert len(nav._close_keys) == 0 and nav._visited == []
    # frontiers now count only what it sees from here on: with nothing seen yet, no free cell is known
    from planners.occupancy import GridConfig, build_occupancy_grid

    walls = [[x, y, 0.5] for x in np.arange(-1, 1, 0.05) for y in (-1.0, 1.0)]
    floor = [[x, y, 0.0] for x in np.arange(-1, 1, 0.05) for y in np.arange(-0.95, 0.95, 0.05)]
    pts = np.array(walls + floor)
    grid = build_occupancy_grid(pts, GridConfig(resolution=0.05, obstacle_z_min=0.08, obstacle_z_max=1.6, padding=1.0))
    narrowed = nav._frontier_grid(grid)
    assert narrowed.known_hw.sum() == narrowed.occupied_hw.sum() < grid.known_hw.sum()


FETCH_CAL = SCENES_ROOT / "calibration-v2" / "fetch-episodes-v2.jsonl"


def test_explore_then_fetch_shows_the_goals_only_after_the_exploration_budget():
    from conceptfusion.tasks import EXPLORE_GOAL

    ep = dataclasses.replace(load_episodes(FETCH_CAL).episodes[0], explore_steps=5)
    env = _env(ep)
    obs, info = env.reset(seed=0, options={"episode": ep})
    assert obs["goal"] == EXPLORE_GOAL and info["exploring"]
    for k in range(1, 5):  # a stop while exploring is ignored: the base stands still, the episode goes on
        obs, reward, term, trunc, info = env.step(np.array([0.3, 0.0, 1.0 if k == 1 else 0.0]))
        assert obs["goal"] == EXPLORE_GOAL and info["exploring"] and not term and reward == 0.0
    assert info["path_length"] > 0
    obs, reward, term, trunc, info = env.step(np.array([0.0, 0.5, 0.0]))  # the fifth step spends the budget
    assert obs["goal"] == ep.goals[0].description and not info["exploring"] and info["goal_index"] == 0
    assert info["path_length"] == 0.0 and info["shortest_path_length"] > 0  # SPL counts from here
    env.close()


def test_explore_steps_is_checked_in_episode_files(tmp_path):
    root, path = _copy(tmp_path, lambda ep: ep.update(explore_steps=ep["max_steps"]))
    with pytest.raises(EpisodeFormatError, match=r"line 2: 'explore_steps' expected an integer in \[0, max_steps\) = \[0, 500\), got 500"):
        load_episodes(path, scenes_root=root)
    tab = tmp_path / "tab.jsonl"
    lines = (SCENES_ROOT / "tabletop-v2" / "episodes-v2.jsonl").read_text().splitlines()[:2]
    rec = json.loads(lines[1])
    rec["explore_steps"] = 2
    tab.write_text(lines[0] + "\n" + json.dumps(rec) + "\n")
    with pytest.raises(EpisodeFormatError, match="'explore_steps' is for object_search episodes"):
        load_episodes(tab)
    # a file without any keeps writing as before; one with them round-trips
    from sim_envs.scenes.episodes import episodes_text

    eps = load_episodes(FETCH_CAL)
    assert all(e.explore_steps == 200 for e in eps.episodes) and episodes_text(eps) == FETCH_CAL.read_text()


class _NoQueries(_Mapper):
    def locate(self, text):
        raise AssertionError(f"asked the map for {text!r} while exploring")

    locate_present = locate


def test_the_navigator_explores_without_asking_its_map_until_a_goal_is_given():
    from conceptfusion.tasks import EXPLORE_GOAL

    mapper = _NoQueries()
    # a closed box: walls all round, a known floor inside, so no frontier is left
    walls = [[x, y, 0.5] for x in np.arange(-1, 1.01, 0.05) for y in (-1.0, 1.0)]
    walls += [[x, y, 0.5] for y in np.arange(-1, 1.01, 0.05) for x in (-1.0, 1.0)]
    floor = [[x, y, 0.0] for x in np.arange(-0.95, 0.96, 0.05) for y in np.arange(-0.95, 0.96, 0.05)]
    mapper.map.points = np.array(walls + floor)
    nav = MapNavigator(mapper, NavigatorConfig())
    nav._goal = EXPLORE_GOAL
    assert not nav._locate().found and nav._locate().reason == "exploring: no goal yet"
    action = nav._plan(np.array([0.0, 0.0, 0.0]))  # an empty map: no frontier, so it looks around
    assert action[2] == 0.0 and action[1] > 0 and "no frontier left, looking around" in nav.log[-1]
