"""cf/ObjectSearch: dynamics, collisions, success and SPL, determinism, bad input."""

import math

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from sim_envs.scenes.episodes import Episode, Goal
from planners.geodesic import geodesic_to_goal
from sim_envs.envs.object_search import ObjectSearchEnv, box_distance_xy
from sim_envs.scenes.search_episodes import default_search_episodes


@pytest.fixture(scope="module")
def episodes():
    return default_search_episodes().episodes


@pytest.fixture()
def env():
    e = ObjectSearchEnv(width=64, height=48)
    yield e
    e.close()


def test_shipped_episodes(episodes):
    assert len(episodes) >= 50
    assert len({e.scene for e in episodes}) >= 10
    for ep in episodes:
        assert ep.start_pose is not None and len(ep.goals) == 1 and ep.instruction.startswith("the ")


def test_check_env(episodes):
    e = ObjectSearchEnv(width=64, height=48, episodes=episodes[:3])
    check_env(e, skip_render_check=True)
    e.close()


def test_geodesic_goes_around_walls():
    free = np.ones((20, 20), bool)
    free[0:15, 10] = False
    goal = np.zeros_like(free)
    goal[2, 15] = True
    d = geodesic_to_goal(free, np.zeros(2), 0.1, (0.55, 0.25), goal)
    assert d > 1.0  # the straight line (1.0 m) crosses the wall; the way round is longer
    assert math.isinf(geodesic_to_goal(free, np.zeros(2), 0.1, (0.55, 0.25), np.zeros_like(free)))
    assert box_distance_xy(np.array([0.0, 0.0]), (1.0, -1.0), (2.0, 1.0)) == pytest.approx(1.0)
    assert box_distance_xy(np.array([1.5, 0.0]), (1.0, -1.0), (2.0, 1.0)) == 0.0


def test_motion_odometry_and_path_length(env, episodes):
    obs, info = env.reset(options={"episode": episodes[0]})
    x0 = obs["base_pose"].copy()
    obs, r, term, trunc, info = env.step(np.array([0.0, 1.0, 0.0], np.float32))
    assert obs["base_pose"][2] == pytest.approx(math.remainder(x0[2] + 0.5, 2 * math.pi), abs=1e-6)
    assert info["path_length"] == 0.0
    # The camera follows the base: its optical axis points along the new heading.
    fwd = obs["cam_to_world"][:3, 2]
    assert math.atan2(fwd[1], fwd[0]) == pytest.approx(obs["base_pose"][2], abs=1e-3)
    assert obs["cam_to_world"][2, 3] == pytest.approx(env.camera_height, abs=1e-3)


def test_walls_stop_the_base(env, episodes):
    obs, info = env.reset(options={"episode": episodes[0]})
    for _ in range(60):  # drive straight: sooner or later a wall or furniture is in the way
        obs, r, term, trunc, info = env.step(np.array([0.6, 0.0, 0.0], np.float32))
        if info["collisions"]:
            break
    assert info["collisions"] > 0
    assert env._is_free(obs["base_pose"][:2])
    assert info["path_length"] < 60 * 0.3


def test_success_and_spl_when_stopping_next_to_the_goal(env, episodes):
    ep = episodes[0]
    env.reset(options={"episode": ep})
    lo, hi = env.goal_box[0, :2], env.goal_box[1, :2]
    # Put the base at a free cell within 0.8 m of the goal box, then stop.
    cx, cy = env._occ.centres()
    d = np.hypot(np.maximum(np.maximum(lo[0] - cx, 0), cx - hi[0]), np.maximum(np.maximum(lo[1] - cy, 0), cy - hi[1]))
    r, c = np.argwhere(env._free & (d < 0.8))[0]
    env._pose[:2] = (cx[r, c], cy[r, c])
    obs, reward, term, trunc, info = env.step(np.array([0, 0, 1], np.float32))
    assert term and not trunc and info["success"] and reward == 1.0
    assert info["spl"] == pytest.approx(1.0)  # path length 0 <= shortest: SPL = l / max(l, p) = 1
    env.reset(options={"episode": ep})
    obs, reward, term, trunc, info = env.step(np.array([0, 0, 1], np.float32))  # stop at the start: far away
    assert term and not info["success"] and info["spl"] == 0.0 and info["distance_to_goal"] > 1.0


def test_truncation_clipping_and_bad_actions(episodes):
    e = ObjectSearchEnv(width=32, height=24, max_steps=3)
    e.reset(options={"episode": episodes[1]})
    obs, r, term, trunc, info = e.step(np.array([5.0, 9.0, -3.0], np.float32))  # clipped to [0.6, 1.5, 0]
    assert info["path_length"] <= 0.6 * 0.5 + 1e-6
    with pytest.raises(ValueError, match="finite"):
        e.step(np.array([np.nan, 0, 0]))
    with pytest.raises(ValueError, match="shape"):
        e.step(np.zeros(2))
    e.step(np.zeros(3, np.float32))
    _, _, term, trunc, _ = e.step(np.zeros(3, np.float32))
    assert trunc and not term
    bad = Episode("x", episodes[1].scene, 0, "the thing", (Goal(episodes[1].goals[0].object_id),), (-100.0, -100.0, 0.0), 10)
    with pytest.raises(ValueError, match="outside the apartment's bounds"):
        e.reset(options={"episode": bad})
    e.close()


def test_same_episode_same_frames(episodes):
    frames = []
    for _ in range(2):
        e = ObjectSearchEnv(width=64, height=48)
        obs, _ = e.reset(options={"episode": episodes[2]})
        for a in ([0.5, 0.3, 0], [0.2, -0.5, 0]):
            obs, *_ = e.step(np.array(a, np.float32))
        frames.append((obs["rgb"].copy(), obs["base_pose"].copy()))
        e.close()
    assert np.array_equal(frames[0][0], frames[1][0]) and np.array_equal(frames[0][1], frames[1][1])


def test_without_segmentation_the_observations_are_the_same_and_info_has_none():
    frames = {}
    for seg in (True, False):
        e = ObjectSearchEnv(width=64, height=48, segmentation=seg)
        obs, info = e.reset(seed=1)
        obs, *_, info = e.step(np.array([0.2, 0.5, 0.0], np.float32))
        assert ("segmentation" in info) == seg
        frames[seg] = obs
        e.close()
    for key in ("rgb", "depth", "cam_to_world", "base_pose"):
        assert np.array_equal(frames[True][key], frames[False][key], equal_nan=True), key
    with pytest.raises(TypeError, match="segmentation: expected True or False"):
        ObjectSearchEnv(segmentation=1)


def test_without_the_camera_the_base_and_every_metric_move_as_with_it(episodes):
    """camera=False renders nothing: the observations are the pose and goal only, and the same
    actions (walls hit included) give the same poses, info and rewards as with the camera on."""
    actions = [[0.5, 0.3, 0], [0.6, 0.0, 0]] * 12 + [[0.1, -1.0, 0], [0.0, 0.0, 1]]
    runs = {}
    for camera in (True, False):
        e = ObjectSearchEnv(width=64, height=48, segmentation=False, camera=camera, episodes=episodes[:3])
        if not camera:
            check_env(e, skip_render_check=True)
            assert set(e.observation_space.spaces) == {"base_pose", "goal"}
        obs, info = e.reset(options={"episode": episodes[2]})
        steps = [(obs, 0.0, False, False, info)]
        for a in actions:
            steps.append(e.step(np.array(a, np.float32)))
            if steps[-1][2] or steps[-1][3]:
                break
        assert e.observation_space.contains(steps[-1][0])
        runs[camera] = steps
        e.close()
    assert len(runs[True]) == len(runs[False]) and runs[False][-1][4]["collisions"] > 0
    for (o1, r1, t1, u1, i1), (o0, r0, t0, u0, i0) in zip(runs[True], runs[False]):
        assert set(o0) == {"base_pose", "goal"} and o1["goal"] == o0["goal"]
        assert np.array_equal(o1["base_pose"], o0["base_pose"]) and (r1, t1, u1) == (r0, t0, u0)
        for key in ("distance_to_goal", "steps", "collisions", "path_length", "success", "spl", "object_names"):
            if key in i1:
                assert i1[key] == i0[key], key


@pytest.mark.parametrize("kwargs, match", [
    ({"camera": 0}, "camera: expected True or False"),
    ({"camera": False}, "camera=False renders nothing.*segmentation=False.*got segmentation=True"),
    ({"camera": False, "segmentation": False, "render_mode": "rgb_array"}, "render_mode=None.*'rgb_array'"),
])
def test_bad_camera_settings(kwargs, match):
    with pytest.raises((TypeError, ValueError), match=match):
        ObjectSearchEnv(**kwargs)
