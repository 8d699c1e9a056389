"""Non-privileged agents and baselines never read ground truth.

Every registered agent with ``privileged=False`` is handed, at each step of a short episode, an
``info`` full of traps: a dict with the environment's keys but wrong-but-plausible values (goal
boxes moved, labels shuffled, flags flipped) that records every access. The agent must not
touch it, and its actions must equal those of the same episode run with ``info=None``. The
spatial suite's 2.5D and 3D baselines must answer the same from a scan whose ground truth
(label images, label names, scene graph, boxes) is replaced by traps; the oracle, which is
privileged, must trip them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.registry import AGENTS, AgentSpec, make_agent, register_agent
from harness.maps.scan import SceneScan, load_shipped_scene, scan_scene
from harness.maps.spatial import answer_questions, generate_questions
from harness.runner.suites import get_suite
from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode
from sim_envs.scenes.episodes import load_episodes

_STEPS = {"tabletop_rearrange": 3, "object_search": 12}
_ENV_KWARGS = {"tabletop_rearrange": {"width": 128, "height": 96, "scan_frames": 6}, "object_search": {"width": 160, "height": 120}}
_SUITE = {"tabletop_rearrange": "regression-rearrange", "object_search": "regression-search"}


class Touched(AssertionError):
    """A trap was read."""


def _wrong(value):
    """A wrong-but-plausible stand-in of the same kind and shape."""
    if isinstance(value, (bool, np.bool_)):
        return not bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value) + 3
    if isinstance(value, (float, np.floating)):
        return float(value) * 1.5 + 0.75
    if isinstance(value, np.ndarray):
        flipped = np.roll(value, 1, axis=tuple(range(value.ndim))) if value.ndim else value
        return flipped + 0.5 if value.dtype.kind == "f" else (flipped[::-1].copy() if value.ndim else flipped)
    if isinstance(value, str):
        return value[::-1]
    if isinstance(value, dict):
        return {k: _wrong(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_wrong(v) for v in reversed(value)) if not hasattr(value, "_fields") else value
    return value


class TrapInfo(dict):
    """The real info's keys with wrong values; every read is logged (and the values would mislead)."""

    def __init__(self, real: dict, log: list):
        super().__init__({k: _wrong(v) for k, v in real.items()})
        self._log = log

    def _touch(self, what, *args):
        self._log.append((what, *args))

    def __getitem__(self, key):
        self._touch("getitem", key)
        return super().__getitem__(key)

    def get(self, key, default=None):
        self._touch("get", key)
        return super().get(key, default)

    def __contains__(self, key):
        self._touch("contains", key)
        return super().__contains__(key)

    def __iter__(self):
        self._touch("iter")
        return super().__iter__()

    def __len__(self):
        self._touch("len")
        return super().__len__()

    def keys(self):
        self._touch("keys")
        return super().keys()

    def values(self):
        self._touch("values")
        return super().values()

    def items(self):
        self._touch("items")
        return super().items()

    def copy(self):
        self._touch("copy")
        return super().copy()

    def __or__(self, other):
        self._touch("or")
        return super().__or__(other)

    def __ror__(self, other):
        self._touch("ror")
        return super().__ror__(other)

    def __eq__(self, other):
        self._touch("eq")
        return super().__eq__(other)

    __hash__ = None

    def __getattr__(self, name):
        self._touch("getattr", name)
        raise AttributeError(name)


class Trap:
    """Any ground truth an unprivileged path must not read: every attribute, item or call raises."""

    def __init__(self, what: str):
        object.__setattr__(self, "_what", what)

    def _fail(self, *args):
        raise Touched(f"read {object.__getattribute__(self, '_what')}: {args}")

    def __getattr__(self, name):
        self._fail("attribute", name)

    def __getitem__(self, key):
        self._fail("item", key)

    def __iter__(self):
        self._fail("iter")

    def __len__(self):
        self._fail("len")

    def __bool__(self):
        self._fail("bool")

    def __contains__(self, key):
        self._fail("contains", key)

    def __call__(self, *args, **kwargs):
        self._fail("call")


def _episode(task: str):
    suite = get_suite(_SUITE[task])
    return load_episodes(suite.episodes_file).episodes[0]


def _env(task: str):
    if task == "tabletop_rearrange":
        from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv

        return TabletopRearrangeEnv(**_ENV_KWARGS[task])
    from sim_envs.envs.object_search import ObjectSearchEnv

    return ObjectSearchEnv(**_ENV_KWARGS[task])


def _actions(env, agent, episode, task: str, *, trap: bool) -> tuple[list[np.ndarray], list]:
    """Run ``agent`` for a few steps; ``trap``: hand it a TrapInfo each step, else None."""
    log: list = []
    obs, info = env.reset(seed=0, options={"episode": episode})
    agent.reset(seed=7)
    actions = []
    for _ in range(_STEPS[task]):
        action = agent.act(obs, TrapInfo(info, log) if trap else None)
        actions.append(np.array(action, copy=True))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    return actions, log


UNPRIVILEGED = sorted(name for name, spec in AGENTS.items() if not spec.privileged and spec.task in _STEPS)


def test_every_registered_task_has_unprivileged_agents_to_check():
    assert {AGENTS[n].task for n in UNPRIVILEGED} == set(_STEPS)
    assert {"map-pusher", "frame-pusher", "random-pusher", "map-navigator", "frame-searcher", "random-walker"} <= set(UNPRIVILEGED)


@pytest.mark.parametrize("name", UNPRIVILEGED)
def test_unprivileged_agent_never_reads_info(name):
    task = AGENTS[name].task
    env = _env(task)
    try:
        episode = _episode(task)
        agent = make_agent(name)
        assert agent.privileged is False
        plain, _ = _actions(env, agent, episode, task, trap=False)
        trapped, log = _actions(env, make_agent(name), episode, task, trap=True)
    finally:
        env.close()
    assert log == [], f"{name} read the info: {log[:5]}"
    assert len(plain) == len(trapped) and all(np.array_equal(a, b) for a, b in zip(plain, trapped))


def test_the_trap_catches_an_agent_that_reads_info():
    class Peeker:
        privileged = False

        def reset(self, seed=None):
            pass

        def act(self, observation, info=None):
            return info.get("goal_aabb") if info else None

    log: list = []
    assert Peeker().act({}, TrapInfo({"goal_aabb": np.zeros((2, 3))}, log)) is not None
    assert log == [("len",), ("get", "goal_aabb")]
    assert np.array_equal(TrapInfo({"x": np.zeros(3)}, []).get("x"), np.full(3, 0.5))  # and its values are wrong


class _InfoSpy:
    """Records what the runner hands it, then stops the episode."""

    seen: list = []
    privileged = False

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        _InfoSpy.seen.append((self.privileged, info))
        return np.array([0, 0, 0, 0, 1], np.float32)


class _PrivilegedSpy(_InfoSpy):
    privileged = True


def test_the_runner_withholds_info_from_unprivileged_agents():
    episode = _episode("tabletop_rearrange")
    _InfoSpy.seen.clear()
    register_agent(AgentSpec("test-info-spy", _InfoSpy, "tabletop_rearrange", "records its info (test)", {}))
    register_agent(AgentSpec("test-info-spy-privileged", _PrivilegedSpy, "tabletop_rearrange", "records its info (test)", {},
                             privileged=True))
    try:
        for name in ("test-info-spy", "test-info-spy-privileged"):
            rec = run_episode(EpisodeJob(run_id="t", suite="s", task="tabletop_rearrange", agent=name, agent_kwargs={},
                                         episode=episode, env_kwargs=_ENV_KWARGS["tabletop_rearrange"]))
            assert rec["status"] == "ok", rec["error"]
    finally:
        close_cached_envs()
        for name in ("test-info-spy", "test-info-spy-privileged"):
            AGENTS.pop(name, None)
    assert [p for p, _ in _InfoSpy.seen] == [False, True]
    assert _InfoSpy.seen[0][1] is None and isinstance(_InfoSpy.seen[1][1], dict) and "success" in _InfoSpy.seen[1][1]


@pytest.fixture(scope="module")
def small_scan():
    return scan_scene(load_shipped_scene("tabletop-0111"), frames=6, width=96, height=72)


def _blind(scan: SceneScan) -> SceneScan:
    """The scan with every piece of ground truth replaced by a trap."""
    return SceneScan(scene=Trap("scene"), sim=Trap("sim"), frames=[dataclasses.replace(f, segmentation=None) for f in scan.frames],
                     label_names=Trap("label names"), object_boxes=Trap("object boxes"), graph=Trap("scene graph"),
                     geom_labels=Trap("geom labels"))


@pytest.mark.parametrize("method", ["2.5d", "3d"])
def test_spatial_baselines_answer_without_ground_truth(small_scan, method):
    questions = generate_questions(small_scan, seed=0)
    assert len(questions) >= 16
    with_gt = answer_questions(small_scan, questions, method, "color", parser="pattern")
    blind = answer_questions(_blind(small_scan), questions, method, "color", parser="pattern")
    assert blind == with_gt
    if method == "2.5d":
        assert any(q["frame"] not in (None, 0) for q in blind)  # a frame is chosen per question, not always the first


def test_the_oracle_spatial_baseline_trips_the_traps(small_scan):
    questions = generate_questions(small_scan, seed=0)[:2]
    with pytest.raises(Touched, match="label names"):
        answer_questions(_blind(small_scan), questions, "2.5d", "oracle", parser="pattern")


@pytest.mark.parametrize("name", sorted(n for n, s in AGENTS.items() if s.privileged and s.task in _STEPS))
def test_a_privileged_agent_does_read_the_trap(name):
    task = AGENTS[name].task
    env = _env(task)
    log: list = []
    try:
        obs, info = env.reset(seed=0, options={"episode": _episode(task)})
        agent = make_agent(name)
        agent.reset(seed=7)
        try:
            agent.act(obs, TrapInfo(info, log))
        except Exception:  # misled by the wrong values: it read them
            pass
    finally:
        env.close()
    assert agent.privileged is True and log
