"""Bad input to the three environments (sim_envs/envs): constructor arguments, reset seeds and
options, episodes built in code, actions, and calls out of turn (the Gymnasium convention: no
step before reset, after the episode ended or after close, until the next reset)."""

import dataclasses
import math

import numpy as np
import pytest

from conceptfusion.errors import EnvStateError, MissingFileError, SimError, SimTypeError, UnknownNameError
from sim_envs.envs.object_search import ObjectSearchEnv
from sim_envs.envs.scene_scan import SceneScanEnv
from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv
from sim_envs.scenes.episodes import SCENES_ROOT, EpisodeSet, Goal, load_episodes, resolve_scene
from sim_envs.scenes.search_episodes import default_search_episodes

W, H = 32, 24
TABLETOP_FILE = SCENES_ROOT / "tabletop" / "episodes-v1.jsonl"
STOP5 = np.array([0, 0, 0, 0, 1.0])
NOOP5 = np.array([0.59, 0.39, 0.0, 0.01, 0.0])  # a push at the table corner: nothing to touch


@pytest.fixture(scope="module")
def search_episodes():
    return default_search_episodes().episodes


@pytest.fixture(scope="module")
def tabletop_episodes():
    return load_episodes(TABLETOP_FILE)


@pytest.fixture(scope="module")
def scan_env():
    env = SceneScanEnv(num_frames=2, width=W, height=H)
    yield env
    env.close()


@pytest.fixture(scope="module")
def rearrange_env(tabletop_episodes):
    env = TabletopRearrangeEnv(width=W, height=H, episodes=tabletop_episodes, max_steps=2)
    yield env
    env.close()


@pytest.fixture(scope="module")
def search_env(search_episodes):
    env = ObjectSearchEnv(width=W, height=H, episodes=search_episodes[:3], max_steps=2)
    yield env
    env.close()


# --------------------------------------------------------------------------- calls out of turn
def test_scan_step_before_reset():
    env = SceneScanEnv(num_frames=2, width=W, height=H)
    with pytest.raises(EnvStateError, match=r"SceneScan: step\(\) before a successful reset\(\); call reset\(\)"):
        env.step(0)


def test_scan_step_after_the_last_frame_until_reset(scan_env):
    scan_env.reset(seed=0)
    _, _, terminated, _, _ = scan_env.step(0)
    assert terminated
    with pytest.raises(EnvStateError, match=r"SceneScan: the episode is over \(a step returned terminated or truncated\); call reset\(\)"):
        scan_env.step(0)
    scan_env.reset(seed=0)
    scan_env.step(0)  # allowed again


def test_scan_step_after_close():
    env = SceneScanEnv(num_frames=3, width=W, height=H)
    env.reset(seed=0)
    env.close()
    with pytest.raises(EnvStateError, match=r"SceneScan: the environment was closed; call reset\(\)"):
        env.step(0)
    env.reset(seed=0)  # a closed environment can start over
    env.step(0)
    env.close()


def test_rearrange_step_before_reset():
    env = TabletopRearrangeEnv(width=W, height=H)
    with pytest.raises(EnvStateError, match=r"TabletopRearrange: step\(\) before a successful reset\(\)"):
        env.step(NOOP5)


def test_rearrange_step_after_stop_and_after_truncation(rearrange_env, tabletop_episodes):
    rearrange_env.reset(seed=0)
    rearrange_env.step(STOP5)
    with pytest.raises(EnvStateError, match=r"TabletopRearrange: the episode is over"):
        rearrange_env.step(NOOP5)
    rearrange_env.reset(options={"episode": dataclasses.replace(tabletop_episodes.episodes[0], max_steps=2)})
    rearrange_env.step(NOOP5)
    _, _, term, trunc, _ = rearrange_env.step(NOOP5)
    assert trunc and not term
    with pytest.raises(RuntimeError, match=r"the episode is over"):  # EnvStateError is a RuntimeError too
        rearrange_env.step(NOOP5)


def test_rearrange_scan_and_evaluate_before_reset():
    env = TabletopRearrangeEnv(width=W, height=H)
    with pytest.raises(EnvStateError, match=r"TabletopRearrange: scan\(\) needs an episode \(the environment is not reset\)"):
        env.scan(2)
    with pytest.raises(EnvStateError, match=r"TabletopRearrange: evaluate\(\) needs an episode"):
        env.evaluate()


def test_rearrange_step_after_close():
    env = TabletopRearrangeEnv(width=W, height=H)
    env.reset(seed=0)
    env.close()
    with pytest.raises(EnvStateError, match=r"TabletopRearrange: the environment was closed"):
        env.step(NOOP5)


def test_search_step_after_stop_does_not_move(search_env):
    obs, _ = search_env.reset(seed=0)
    _, _, term, _, info = search_env.step(np.array([0.0, 0.0, 1.0]))
    assert term and info["steps"] == 1
    with pytest.raises(EnvStateError, match=r"ObjectSearch: the episode is over \(a step returned terminated or truncated\)"):
        search_env.step(np.array([0.6, 0.0, 0.0]))
    assert np.array_equal(search_env.unwrapped._pose, obs["base_pose"])  # the base did not move after stopping


def test_search_step_after_truncation(search_env):
    search_env.reset(seed=0)
    search_env.step(np.zeros(3))
    _, _, term, trunc, info = search_env.step(np.zeros(3))
    assert trunc and not term and info["steps"] == 2
    with pytest.raises(EnvStateError, match=r"ObjectSearch: the episode is over"):
        search_env.step(np.zeros(3))  # steps no longer count past max_steps


def test_search_step_before_reset_and_ground_truth_before_reset():
    env = ObjectSearchEnv(width=W, height=H)
    with pytest.raises(EnvStateError, match=r"ObjectSearch: step\(\) before a successful reset\(\)"):
        env.step(np.zeros(3))
    with pytest.raises(EnvStateError, match=r"ObjectSearch: goal_box needs an episode"):
        env.goal_box
    with pytest.raises(EnvStateError, match=r"ObjectSearch: camera_eye_target\(\) without a pose needs an episode"):
        env.camera_eye_target()


def test_search_step_after_close_and_reset_after_close(search_episodes):
    env = ObjectSearchEnv(width=W, height=H, episodes=search_episodes[:1])
    env.reset(seed=0)
    env.close()
    with pytest.raises(EnvStateError, match=r"ObjectSearch: the environment was closed"):
        env.step(np.zeros(3))
    env.reset(seed=0)  # the camera is rebuilt (it used to stay closed: AttributeError)
    env.step(np.zeros(3))
    env.close()


def test_search_failed_reset_refuses_steps(search_env, search_episodes):
    search_env.reset(seed=0)
    bad = dataclasses.replace(search_episodes[0], start_pose=(-100.0, -100.0, 0.0))
    with pytest.raises(SimError, match=r"start pose \(-100.00, -100.00\) is outside the apartment's bounds x in \[-?\d"):
        search_env.reset(options={"episode": bad})
    with pytest.raises(EnvStateError, match=r"step\(\) before a successful reset\(\)"):
        search_env.step(np.zeros(3))


def test_search_start_on_furniture_is_inside_an_obstacle(search_env, search_episodes):
    piece = resolve_scene(search_episodes[0].scene, search_episodes[0].scene_seed).furniture[0]
    bad = dataclasses.replace(search_episodes[0], start_pose=(piece.position[0], piece.position[1], 0.0))
    with pytest.raises(SimError, match=r"start pose \(.*\) is inside an obstacle"):
        search_env.reset(options={"episode": bad})


# --------------------------------------------------------------------------- reset seeds and options
@pytest.mark.parametrize(
    "options, error, message",
    [
        ([1], SimTypeError, r"SceneScan: options: expected None or a dict \(valid keys: none\), got list"),
        ("episode", SimTypeError, r"SceneScan: options: expected None or a dict .* got str"),
        ({"episode": 1}, UnknownNameError, r"SceneScan: unknown reset option 'episode' \(SceneScan takes no reset options\)"),
    ],
)
def test_scan_reset_options(scan_env, options, error, message):
    with pytest.raises(error, match=message):
        scan_env.reset(options=options)


@pytest.mark.parametrize(
    "seed, error, message",
    [
        (-1, SimError, r"SceneScan: seed: expected None or an int >= 0, got -1"),
        ("1", SimTypeError, r"SceneScan: seed: expected None or an int >= 0, got str '1'"),
        (True, SimTypeError, r"SceneScan: seed: expected None or an int >= 0, got bool True"),
        (1.5, SimTypeError, r"SceneScan: seed: expected None or an int >= 0, got float 1.5"),
    ],
)
def test_reset_seed(scan_env, seed, error, message):
    with pytest.raises(error, match=message):
        scan_env.reset(seed=seed)


def test_numpy_integer_seed_is_accepted(scan_env):
    a, _ = scan_env.reset(seed=np.int64(3))
    b, _ = scan_env.reset(seed=3)
    assert np.array_equal(a["rgb"], b["rgb"])


@pytest.mark.parametrize(
    "options, error, message",
    [
        ([1], SimTypeError, r"TabletopRearrange: options: expected None or a dict \(valid keys: 'episode', 'episode_index'\), got list"),
        ({"episod": 1}, UnknownNameError, r"TabletopRearrange: unknown reset option 'episod'; did you mean 'episode'"),
        ({"episode_idx": 1}, UnknownNameError, r"unknown reset option 'episode_idx'; did you mean 'episode_index'"),
        ({1: 2}, UnknownNameError, r"unknown reset option 1 \(valid keys: 'episode', 'episode_index'\)"),
        ({"episode": {"episode_id": "x"}}, SimTypeError, r"TabletopRearrange: options\['episode'\]: expected an Episode, got dict"),
        ({"episode_index": 10_000}, SimError, r"options\['episode_index'\]: expected an integer in \[0, \d+\), got 10000"),
        ({"episode_index": -1}, SimError, r"options\['episode_index'\]: expected an integer in \[0, \d+\), got -1"),
        ({"episode_index": True}, SimError, r"options\['episode_index'\]: expected an integer .* got True"),
        ({"episode_index": "0"}, SimError, r"options\['episode_index'\]: expected an integer .* got '0'"),
        ({"episode_index": 0, "episode": None}, SimError, r"TabletopRearrange: options: give 'episode' or 'episode_index', not both"),
    ],
)
def test_rearrange_reset_options(rearrange_env, options, error, message):
    with pytest.raises(error, match=message):
        rearrange_env.reset(options=options)


def test_rearrange_episode_index_needs_an_episode_set():
    env = TabletopRearrangeEnv(width=W, height=H)
    with pytest.raises(SimError, match=r"options\['episode_index'\]: the environment has no episode set; give episodes="):
        env.reset(options={"episode_index": 0})  # used to be ignored silently


def test_rearrange_episode_index_picks_the_episode(rearrange_env, tabletop_episodes):
    _, info = rearrange_env.reset(seed=0, options={"episode_index": 2})
    assert info["episode_id"] == tabletop_episodes.episodes[2].episode_id


@pytest.mark.parametrize(
    "change, error, message",
    [
        ({"goals": ()}, SimError, r"episode '.*': goals: expected a non-empty tuple of Goal"),
        ({"goals": ("obj0",)}, SimError, r"goals: expected a non-empty tuple of Goal"),
        ({"goals": (Goal("obj0", "up"),)}, SimError, r"goals: expected every side 'left' or 'right', got \['up'\]"),
        ({"instruction": "push it!"}, SimError, r"instruction must be 1 to 256 characters of .* got 'push it!'"),
        ({"instruction": ""}, SimError, r"instruction must be 1 to 256 characters"),
        ({"max_steps": 0}, SimError, r"max_steps: expected an int >= 1, got 0"),
        ({"max_steps": 2.5}, SimTypeError, r"max_steps: expected an int >= 1, got float 2.5"),
        ({"scene_seed": "3"}, SimTypeError, r"scene_seed: expected an int >= 0, got str '3'"),
        ({"scene": 5}, SimTypeError, r"scene: expected a str, got int"),
    ],
)
def test_rearrange_episode_fields(rearrange_env, tabletop_episodes, change, error, message):
    bad = dataclasses.replace(tabletop_episodes.episodes[0], **change)
    with pytest.raises(error, match=message):
        rearrange_env.reset(options={"episode": bad})


def test_rearrange_search_episode_is_refused(rearrange_env, search_episodes):
    with pytest.raises(SimError, match=r"goals: expected every side 'left' or 'right', got \[None\]"):
        rearrange_env.reset(options={"episode": search_episodes[0]})


@pytest.mark.parametrize(
    "options, error, message",
    [
        ([1], SimTypeError, r"ObjectSearch: options: expected None or a dict \(valid keys: 'episode', 'episode_index'\), got list"),
        ({"episode_idx": 0}, UnknownNameError, r"ObjectSearch: unknown reset option 'episode_idx'; did you mean 'episode_index'"),
        ({"episode_index": 3}, SimError, r"ObjectSearch: options\['episode_index'\]: expected an integer in \[0, 3\), got 3"),
        ({"episode": "household/x"}, SimTypeError, r"ObjectSearch: options\['episode'\]: expected an Episode, got str"),
        ({"episode": None, "episode_index": 0}, SimError, r"give 'episode' or 'episode_index', not both"),
    ],
)
def test_search_reset_options(search_env, options, error, message):
    with pytest.raises(error, match=message):
        search_env.reset(options=options)


def test_search_episode_index_is_supported(search_env, search_episodes):
    _, info = search_env.reset(options={"episode_index": 2})  # used to be ignored silently
    assert info["episode_id"] == search_episodes[2].episode_id
    _, info = search_env.reset(options={"episode_index": np.int64(1)})
    assert info["episode_id"] == search_episodes[1].episode_id


@pytest.mark.parametrize(
    "change, message",
    [
        ({"start_pose": (math.nan, 0.0, 0.0)}, r"start_pose: expected \(x, y, yaw\), 3 finite numbers, got \(nan, 0.0, 0.0\)"),
        ({"start_pose": None}, r"start_pose: expected \(x, y, yaw\), 3 finite numbers, got None"),
        ({"start_pose": (1.0, 2.0)}, r"start_pose: expected \(x, y, yaw\)"),
        ({"start_pose": ("a", 0, 0)}, r"start_pose: expected \(x, y, yaw\)"),
        ({"instruction": "the mug\n"}, r"instruction must be 1 to 200 characters"),
        ({"goals": (Goal("no-such-object"),)}, r"scene household-\d+ has no object 'no-such-object' \(objects: "),
        ({"goals": ()}, r"goals: expected a non-empty tuple of Goal"),
        ({"max_steps": -1}, r"max_steps: expected an int >= 1, got -1"),
    ],
)
def test_search_episode_fields(search_env, search_episodes, change, message):
    bad = dataclasses.replace(search_episodes[0], **change)
    with pytest.raises(SimError, match=message):
        search_env.reset(options={"episode": bad})


def test_search_goal_id_typo_names_the_nearest(search_env, search_episodes):
    ep = search_episodes[0]
    oid = ep.goals[0].object_id
    bad = dataclasses.replace(ep, goals=(Goal(oid + "x"),))
    with pytest.raises(SimError, match=rf"has no object '{oid}x'; did you mean '{oid}'"):
        search_env.reset(options={"episode": bad})


# --------------------------------------------------------------------------- actions
@pytest.mark.parametrize(
    "action, error, message",
    [
        (np.array([0, np.nan, 0, 0.1, 0]), SimError, r"TabletopRearrange: action: expected finite numbers, got \[0.0, nan"),
        (np.array([0, np.inf, 0, 0.1, 0]), SimError, r"action: expected finite numbers, got \[0.0, inf"),
        (np.zeros(4), SimError, r"action: expected shape \(5,\) \(start_x, start_y, direction_rad, distance, stop\), got shape \(4,\)"),
        (np.zeros((1, 5)), SimError, r"action: expected shape \(5,\) .* got shape \(1, 5\)"),
        (["a", 0, 0, 0, 0], SimTypeError, r"TabletopRearrange: action: expected 5 numbers .* got list"),
        (None, SimTypeError, r"action: expected 5 numbers .* got NoneType None"),
        (np.array([1j, 0, 0, 0, 0]), SimTypeError, r"action: expected 5 numbers"),
    ],
)
def test_rearrange_bad_actions(rearrange_env, action, error, message):
    rearrange_env.reset(seed=0)
    with pytest.raises(error, match=message):
        rearrange_env.step(action)


@pytest.mark.parametrize(
    "action, error, message",
    [
        (np.array([np.nan, 0, 0]), SimError, r"ObjectSearch: action: expected finite numbers, got \[nan, 0.0, 0.0\]"),
        (np.array([0, -np.inf, 0]), SimError, r"ObjectSearch: action: expected finite numbers"),
        (np.zeros(2), SimError, r"ObjectSearch: action: expected shape \(3,\) \[linear, angular, stop\], got shape \(2,\)"),
        ("go", SimTypeError, r"ObjectSearch: action: expected 3 numbers \[linear, angular, stop\], got str 'go'"),
        ({"linear": 0.3}, SimTypeError, r"ObjectSearch: action: expected 3 numbers .* got dict"),
    ],
)
def test_search_bad_actions(search_env, action, error, message):
    search_env.reset(seed=0)
    with pytest.raises(error, match=message):
        search_env.step(action)


@pytest.mark.parametrize(
    "action, message",
    [(1, r"SceneScan: action: expected 0 \(Discrete\(1\)\), got 1"), ("0", r"got '0'"), (0.0, r"got 0.0"), (None, r"got None")],
)
def test_scan_bad_actions(scan_env, action, message):
    scan_env.reset(seed=0)
    with pytest.raises(SimError, match=message):
        scan_env.step(action)


# --------------------------------------------------------------------------- constructors
@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"width": -1}, SimError, r"SceneScan: width: expected an int >= 1, got -1"),
        ({"height": 0}, SimError, r"SceneScan: height: expected an int >= 1, got 0"),
        ({"width": 64.5}, SimTypeError, r"SceneScan: width: expected an int >= 1, got float 64.5"),
        ({"width": "64"}, SimTypeError, r"width: expected an int >= 1, got str '64'"),
        ({"width": True}, SimTypeError, r"width: expected an int >= 1, got bool True"),
        ({"height": 100_000}, SimError, r"SceneScan: height: expected at most 8192 pixels, got 100000"),
        ({"num_frames": 0}, SimError, r"SceneScan: num_frames: expected an int >= 1, got 0"),
        ({"num_frames": 2.0}, SimTypeError, r"num_frames: expected an int >= 1, got float 2.0"),
        ({"fovy_deg": 0}, SimError, r"SceneScan: fovy_deg: expected a finite number > 0 and < 180, got 0"),
        ({"fovy_deg": 180}, SimError, r"fovy_deg: expected a finite number > 0 and < 180, got 180"),
        ({"fovy_deg": math.nan}, SimError, r"fovy_deg: expected a finite number > 0 and < 180, got nan"),
        ({"fovy_deg": "wide"}, SimTypeError, r"fovy_deg: expected a finite number .* got str 'wide'"),
        ({"kind": "houshold"}, UnknownNameError, r"SceneScan: kind: expected one of \['household', 'tabletop'\], got 'houshold'; did you mean 'household'"),
        ({"kind": ["tabletop"]}, UnknownNameError, r"kind: expected one of \['household', 'tabletop'\], got \['tabletop'\]"),
        ({"scene": "tabletop-0111"}, SimTypeError, r"SceneScan: scene: expected None or a Scene, got str"),
        ({"render_mode": "rgb-array"}, SimError, r"render_mode: expected None or 'rgb_array', got 'rgb-array'; did you mean 'rgb_array'"),
        ({"render_mode": "human"}, SimError, r"render_mode: expected None or 'rgb_array', got 'human'"),
        ({"render_mode": ["rgb_array"]}, SimError, r"render_mode: expected None or 'rgb_array', got \['rgb_array'\]"),
    ],
)
def test_scan_constructor(kwargs, error, message):
    with pytest.raises(error, match=message):
        SceneScanEnv(**{"width": W, "height": H, **kwargs})


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"backend": "mujco"}, UnknownNameError, r"TabletopRearrange: backend: expected one of \['mujoco', 'pybullet'\], got 'mujco'; did you mean 'mujoco'"),
        ({"backend": None}, UnknownNameError, r"backend: expected one of \['mujoco', 'pybullet'\], got None"),
        ({"width": -1}, SimError, r"TabletopRearrange: width: expected an int >= 1, got -1"),
        ({"scan_width": 0}, SimError, r"TabletopRearrange: scan_width: expected None or an int >= 1, got 0"),
        ({"scan_height": -3}, SimError, r"scan_height: expected None or an int >= 1, got -3"),
        ({"scan_frames": -1}, SimError, r"scan_frames: expected an int >= 0, got -1"),
        ({"scan_frames": 1.5}, SimTypeError, r"scan_frames: expected an int >= 0, got float 1.5"),
        ({"max_steps": 0}, SimError, r"TabletopRearrange: max_steps: expected an int >= 1, got 0"),
        ({"fovy_deg": -10.0}, SimError, r"fovy_deg: expected a finite number > 0 and < 180"),
        ({"scene": {"id": "x"}}, SimTypeError, r"TabletopRearrange: scene: expected None or a Scene, got dict"),
        ({"scenes_root": "/no/such/folder"}, MissingFileError, r"TabletopRearrange: scenes_root: no folder '/no/such/folder'"),
        ({"scenes_root": 3}, SimTypeError, r"scenes_root: expected None or a folder path, got int"),
        ({"episodes": "/no/such/episodes.jsonl"}, MissingFileError, r"TabletopRearrange: episodes: no episode file '/no/such/episodes.jsonl'"),
        ({"episodes": 123}, SimTypeError, r"TabletopRearrange: episodes: expected None, an episode file path or an EpisodeSet, got int"),
        ({"episodes": EpisodeSet("tabletop_rearrange", 0, ())}, SimError, r"TabletopRearrange: episodes: the episode set holds no episodes"),
        ({"render_mode": "rgb"}, SimError, r"render_mode: expected None or 'rgb_array', got 'rgb'"),
    ],
)
def test_rearrange_constructor(kwargs, error, message):
    with pytest.raises(error, match=message):
        TabletopRearrangeEnv(**{"width": W, "height": H, **kwargs})


def test_rearrange_constructor_refuses_search_episodes():
    with pytest.raises(SimError, match=r"TabletopRearrange: episodes: expected task 'tabletop_rearrange', got 'object_search'"):
        TabletopRearrangeEnv(width=W, height=H, episodes=default_search_episodes())


def test_rearrange_scan_arguments(rearrange_env):
    rearrange_env.reset(seed=0)
    with pytest.raises(SimError, match=r"TabletopRearrange: num_frames: expected an int >= 1, got 0"):
        rearrange_env.scan(0)
    with pytest.raises(SimError, match=r"TabletopRearrange: width: expected None or an int >= 1, got -5"):
        rearrange_env.scan(2, width=-5)
    with pytest.raises(SimTypeError, match=r"num_frames: expected an int >= 1, got str '2'"):
        rearrange_env.scan("2")


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"width": 0}, SimError, r"ObjectSearch: width: expected an int >= 1, got 0"),
        ({"fovy_deg": 200}, SimError, r"ObjectSearch: fovy_deg: expected a finite number > 0 and < 180, got 200"),
        ({"robot_radius": math.nan}, SimError, r"ObjectSearch: robot_radius: expected a finite number > 0, got nan"),
        ({"success_distance": 0}, SimError, r"success_distance: expected a finite number > 0, got 0"),
        ({"control_dt": math.inf}, SimError, r"control_dt: expected a finite number > 0, got inf"),
        ({"camera_height": -1.0}, SimError, r"camera_height: expected a finite number > 0, got -1.0"),
        ({"camera_pitch_deg": 90}, SimError, r"camera_pitch_deg: expected a finite number > -90 and < 90, got 90"),
        ({"camera_pitch_deg": "down"}, SimTypeError, r"camera_pitch_deg: expected a finite number .* got str 'down'"),
        ({"max_steps": 0}, SimError, r"ObjectSearch: max_steps: expected None or an int >= 1, got 0"),
        ({"max_steps": 10.0}, SimTypeError, r"max_steps: expected None or an int >= 1, got float 10.0"),
        ({"episodes": []}, SimError, r"ObjectSearch: episodes: expected at least one Episode \(or None\), got an empty list"),
        ({"episodes": ["household-0000"]}, SimTypeError, r"ObjectSearch: episodes\[0\]: expected an Episode, got str"),
        ({"episodes": 7}, SimTypeError, r"ObjectSearch: episodes: expected None, an episode file path, an EpisodeSet or a list of Episode, got int"),
        ({"episodes": "/no/such/file.jsonl"}, MissingFileError, r"ObjectSearch: episodes: no episode file"),
        ({"episodes": TABLETOP_FILE}, SimError, r"ObjectSearch: episodes: expected task 'object_search', got 'tabletop_rearrange'"),
        ({"scenes_root": "/no/such/folder"}, MissingFileError, r"ObjectSearch: scenes_root: no folder"),
        ({"render_mode": "human"}, SimError, r"render_mode: expected None or 'rgb_array', got 'human'"),
    ],
)
def test_search_constructor(kwargs, error, message):
    with pytest.raises(error, match=message):
        ObjectSearchEnv(**{"width": W, "height": H, **kwargs})


def test_search_accepts_an_episode_set_and_a_file(search_episodes):
    from sim_envs.scenes.search_episodes import DEFAULT_SEARCH_FILE

    for episodes in (default_search_episodes(), DEFAULT_SEARCH_FILE):
        env = ObjectSearchEnv(width=W, height=H, episodes=episodes)
        _, info = env.reset(options={"episode_index": 0})
        assert info["episode_id"] == search_episodes[0].episode_id
        env.close()
