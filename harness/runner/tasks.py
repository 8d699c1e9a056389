"""Episode rollouts per task: build the environment, run an agent through one episode, score it.

This is the only place that joins an environment and an agent. :class:`EpisodeJob` is a
:class:`~harness.runner.jobs.Job`: picklable, and ``job.run()`` (or :func:`run_episode`) returns
its result record (see :mod:`harness.runner.results`). It never raises for what happens inside
the episode: an exception becomes ``status="failed"`` with the error, so a broken agent cannot
stop a run. A job with ``record`` other than ``"none"`` and an ``out_dir`` follows the episode
with an :class:`~harness.replay.record.EpisodeRecorder` and writes its recording into
``out_dir/replays/`` (every episode, or the failed ones and one success per suite and agent), passing it the record's extras (goal, stop reason) for the video's last frame; the recorder only reads, so the
episode's metrics are the same with recording on or off.
"""

from __future__ import annotations

import time
import traceback
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from agents.registry import AGENTS, make_agent
from harness.replay.record import EpisodeRecorder
from harness.replay.video import render_videos_of
from harness.report.paths import REPLAYS_DIR, replay_stem
from harness.runner.jobs import check_deadline, import_plugins, job_record
from harness.runner.results import agent_label
from harness.runner.stop_reasons import SearchTrace, rearrange_stop_reason, search_stop_reason, status_stop_reason
from sim_envs.assets.library import is_library_asset
from sim_envs.scenes.episodes import Episode
from sim_envs.scenes.splits import object_group

__all__ = ["EpisodeJob", "EXPECTED_EPISODE_S", "run_episode", "episode_seed", "episode_recorder", "TASK_RUNNERS", "close_cached_envs",
           "env_kwargs_for"]


EXPECTED_EPISODE_S: dict[tuple[str, str | None], float] = {
    ("object_search", "map-navigator"): 20.0, ("object_search", "frame-searcher"): 16.0,
    ("object_search", "oracle-searcher"): 1.0, ("object_search", "random-walker"): 0.4, ("object_search", None): 10.0,
    ("tabletop_rearrange", "map-pusher"): 3.0, ("tabletop_rearrange", "frame-pusher"): 1.1,
    ("tabletop_rearrange", "oracle-pusher"): 0.5, ("tabletop_rearrange", "random-pusher"): 0.5, ("tabletop_rearrange", None): 2.0,
}
"""Rough seconds per episode by (task, agent), ``None`` for any other agent (measured with two
workers on two cores); only their order matters: it decides which jobs start first."""


@dataclass(frozen=True)
class EpisodeJob:
    """One episode for one agent: everything a worker process needs, picklable (a
    :class:`~harness.runner.jobs.Job`)."""

    run_id: str
    suite: str
    task: str
    agent: str
    agent_kwargs: dict
    episode: Episode
    seed: int = 0
    env_kwargs: dict = field(default_factory=dict)
    timeout_s: float = 600.0
    """Wall-clock limit of the episode (every backend; see :mod:`harness.runner.backends`)."""
    plugins: tuple[str, ...] = ()
    """Modules to import before the agent is built (they register user agents)."""
    record: str = "none"
    """Episode recording: ``"failures"``, ``"all"`` or ``"none"`` (see :mod:`harness.replay.record`)."""
    out_dir: str | None = None
    """Run folder (absolute) whose ``replays/`` receives the recording; None: nothing is recorded."""

    @property
    def encoder(self) -> str:
        return str(self.agent_kwargs.get("encoder", "none"))

    @property
    def label(self) -> str:
        return f"{agent_label(self.agent, self.agent_kwargs)} {self.episode.episode_id}"

    @property
    def expected_s(self) -> float:
        """Rough length of the episode in seconds (:data:`EXPECTED_EPISODE_S`): the backends
        start the longest jobs first."""
        return EXPECTED_EPISODE_S.get((self.task, self.agent), EXPECTED_EPISODE_S.get((self.task, None), 1.0))

    def key_record(self) -> dict:
        """The fields that identify this episode's record (see :func:`harness.runner.results.record_key`)."""
        return {"suite": self.suite, "agent": self.agent, "agent_kwargs": dict(self.agent_kwargs), "encoder": self.encoder,
                "episode_id": self.episode.episode_id, "seed": self.seed}

    def run(self) -> list[dict]:
        """Run the episode: its one record (see :func:`run_episode`)."""
        return [run_episode(self)]

    def failure_record(self, status: str, error: str, wall_s: float) -> dict:
        """The record of the episode when its worker timed out or died."""
        return job_record(self, status=status, error=error, metrics={"success": False}, timings={"wall_s": wall_s},
                          extras=_ended_extras(self, status))


def episode_seed(job: EpisodeJob) -> int:
    """The agent's seed for one episode: the run's seed mixed with the episode id, so that random
    agents draw differently per episode and identically on every backend and re-run."""
    return zlib.crc32(f"{job.episode.episode_id}:{job.seed}".encode()) & 0x7FFFFFFF


_ENV_CACHE: dict[tuple, Any] = {}


def _cached_env(key: tuple, make: Callable[[], Any]):
    """One environment per (task, settings) per process: scene builds and GL contexts are reused."""
    env = _ENV_CACHE.get(key)
    if env is None:
        env = _ENV_CACHE[key] = make()
    return env


def close_cached_envs() -> None:
    """Close every cached environment of this process."""
    for env in _ENV_CACHE.values():
        try:
            env.close()
        except Exception:  # pragma: no cover - best effort on shutdown
            pass
    _ENV_CACHE.clear()


def env_kwargs_for(task: str, env_kwargs: dict, agent, *, records: bool = False) -> dict:
    """A suite's environment settings for ``task`` as an ``agent`` gets them, with the
    ground-truth segmentation rendered only for a
    privileged agent: the others never see ``info``, and skipping its render pass saves a third
    of a tabletop episode's rendering without changing any observation. A tabletop agent that
    says it never reads the orbit scan (``reads_scan`` False: the single-frame and random pushers,
    the oracle) gets no scan either: rendering it costs a fifth of such an episode, and nothing
    it reads changes. A search agent that says it never looks (``reads_images`` False: the random
    walker, the floor-plan oracle) gets no camera at all (``camera=False``: nine tenths of such
    an episode's CPU went to rendering frames nobody read) unless the episode ``records``
    (a recording keeps the frames for its replay). Agents without the attributes get everything
    the suite sets."""
    kwargs = {"segmentation": bool(getattr(agent, "privileged", False)), **env_kwargs}
    if task == "tabletop_rearrange" and kwargs.get("scan_frames") and getattr(agent, "reads_scan", True) is False:
        kwargs["scan_frames"] = 0
    if (task == "object_search" and not records and "camera" not in env_kwargs
            and getattr(agent, "reads_images", True) is False):
        kwargs.update(camera=False, segmentation=False)
    return kwargs


def _search_env(kwargs: dict):
    from sim_envs.envs.object_search import ObjectSearchEnv

    return ObjectSearchEnv(**kwargs)


def _rearrange_env(kwargs: dict):
    from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv

    return TabletopRearrangeEnv(**kwargs)


def _rollout(env, agent, job: EpisodeJob, *, on_step: Callable[[dict, dict], None] | None = None,
             recorder: EpisodeRecorder | None = None):
    t_env = t_agent = 0.0
    t0 = time.perf_counter()
    obs, info = env.reset(seed=job.seed, options={"episode": job.episode})
    t_env += time.perf_counter() - t0
    check_deadline("env.reset returned")
    agent.reset(seed=episode_seed(job))
    check_deadline("agent.reset returned")
    privileged = bool(getattr(agent, "privileged", False))
    if on_step:
        on_step(obs, info)
    if recorder:
        recorder.begin(env, obs, info)
    steps = 0
    while True:
        t0 = time.perf_counter()
        action = agent.act(obs, info if privileged else None)
        t1 = time.perf_counter()
        check_deadline("agent.act returned")
        if recorder:
            recorder.act(action)
        t1r = time.perf_counter()
        obs, reward, terminated, truncated, info = env.step(action)
        t2 = time.perf_counter()
        check_deadline("env.step returned")
        t_agent += t1 - t0
        t_env += t2 - t1r
        steps += 1
        if on_step:
            on_step(obs, info)
        if recorder:
            recorder.step(obs, reward, info)
        if terminated or truncated:
            return info, steps, {"env_s": t_env, "agent_s": t_agent}, bool(truncated and not terminated)


def _goal_text(job: EpisodeJob) -> str:
    """The goal as the agent read it: a search's ``goal`` observation (a chain's goals, shown one
    at a time, in order and joined with " then "), a tabletop's ``instruction`` (which names every
    object to push and its side)."""
    goals = job.episode.goals
    if job.task == "object_search" and len(goals) > 1 and all(g.description for g in goals):
        return " then ".join(g.description for g in goals)
    return job.episode.instruction


def _sim_of(job: EpisodeJob) -> str:
    """The simulator an episode runs in: its suite's ``backend`` setting (default ``"mujoco"``)."""
    return str(job.env_kwargs.get("backend", "mujoco"))


def _ended_extras(job: EpisodeJob, status: str) -> dict:
    """``goal``, ``stop_reason`` and ``sim`` of an episode that timed out or crashed (status
    ``timeout``, ``failed``)."""
    return {"goal": _goal_text(job), "stop_reason": status_stop_reason(status), "sim": _sim_of(job)}


def _description(job: EpisodeJob, scene=None) -> dict:
    """How the episode's first goal is named (v2 episodes: ``description_kind``) and how seen its
    object is (``goal_split``: its :func:`~sim_envs.scenes.splits.object_group` when it is a
    library instance and ``scene`` is given), each left out when it does not apply. Report
    metadata only: no agent reads it."""
    goal = job.episode.goals[0] if job.episode.goals else None
    out = {"description_kind": goal.description_kind} if goal is not None and goal.description_kind else {}
    if goal is not None and scene is not None:
        obj = scene.object(goal.object_id)
        if is_library_asset(obj.asset):
            out["goal_split"] = object_group(obj)
    return out


def _run_search(job: EpisodeJob, agent, recorder: EpisodeRecorder | None = None) -> tuple[dict, dict, str | None, dict]:
    kwargs = env_kwargs_for(job.task, job.env_kwargs, agent, records=recorder is not None)
    env = _cached_env(("object_search", tuple(sorted(kwargs.items()))), lambda: _search_env(kwargs))
    path: list[list[float]] = []
    trace = SearchTrace()

    def on_step(obs, info):
        path.append([round(float(v), 3) for v in obs["base_pose"][:2]])
        trace.observe(obs, info)

    info, steps, timings, truncated = _rollout(env, agent, job, on_step=on_step, recorder=recorder)
    box = env.unwrapped.goal_box
    goal = env.unwrapped.scene.object(job.episode.goals[0].object_id)
    metrics = {
        "success": bool(info["success"]), "spl": float(info["spl"]), "distance_to_goal": float(info["distance_to_goal"]),
        "steps": int(info["steps"]), "collisions": int(info["collisions"]), "path_length": float(info["path_length"]),
        "shortest_path_length": float(info["shortest_path_length"]),
    }
    chain = len(job.episode.goals)
    if chain > 1:  # a multi-goal search: how far along the chain it got, per position (VLMaps' "k in a row")
        reached = int(info["goals_reached"])
        metrics.update({"goals_reached": reached, "chain_length": chain,
                        **{f"reached_{k}": reached >= k for k in range(1, chain + 1)}})
    extras = {
        "path_xy": path, "start_xy": path[0] if path else None,
        "goal_xy": [round(float(v), 3) for v in (box[0, :2] + box[1, :2]) / 2], "scene": job.episode.scene,
        **_description(job, env.unwrapped.scene),
        "goal": _goal_text(job), "stop_reason": search_stop_reason(trace.end(info, truncated=truncated)),
        "success_radius": trace.success_radius,
        **({"instruction_kind": job.episode.instruction_kind} if job.episode.instruction_kind else {}),
        **_agent_extras(agent),
    }
    if extras.get("planner", {}).get("failure") and not metrics["success"]:
        extras["stop_reason"] = "planner_failure"
    return metrics, timings, goal.category, extras


def _agent_extras(agent) -> dict:
    """What an agent asks its record to keep (``record_extras()``, a JSON-able dict; the
    instruction agents' planner calls): nothing for agents without the method."""
    get = getattr(agent, "record_extras", None)
    return dict(get()) if callable(get) else {}


def _run_rearrange(job: EpisodeJob, agent, recorder: EpisodeRecorder | None = None) -> tuple[dict, dict, str | None, dict]:
    kwargs = env_kwargs_for(job.task, job.env_kwargs, agent)
    env = _cached_env(("tabletop_rearrange", tuple(sorted(kwargs.items()))), lambda: _rearrange_env(kwargs))
    info, steps, timings, _ = _rollout(env, agent, job, recorder=recorder)
    ev = info.get("evaluation", {})
    scene = env.unwrapped.sim.scene
    judged = env.unwrapped.evaluate()
    targets = {g.object_id for g in job.episode.goals}
    stop_reason = rearrange_stop_reason(success=bool(info["success"]), displacement_n=judged.displacement,
                                        target_n=[o.id in targets for o in scene.objects], targets_done=judged.targets_done)
    category = scene.object(job.episode.goals[0].object_id).category if job.episode.goals else None
    metrics = {"success": bool(info["success"]), "steps": int(info["steps"])}
    for key in ("targets_on_side", "max_distractor_shift", "targets_done_fraction"):
        if isinstance(ev.get(key), (int, float, bool)):
            metrics[key] = ev[key]
    return metrics, timings, category, {"scene": job.episode.scene, **_description(job, scene), "goal": _goal_text(job),
                                        "stop_reason": stop_reason}


TASK_RUNNERS: dict[str, Callable[..., tuple[dict, dict, str | None, dict]]] = {
    "object_search": _run_search,
    "tabletop_rearrange": _run_rearrange,
}
"""Per task: (job, agent, recorder=None) -> (metrics, timings, goal category, extras); the
recorder (an :class:`~harness.replay.record.EpisodeRecorder` or None) follows the rollout. Both
tasks' extras carry ``goal`` (the goal text as the agent read it) and ``stop_reason`` (a word of
:data:`~harness.runner.stop_reasons.STOP_REASONS`); a search's also ``success_radius`` (m). Every
record's extras also say which simulator ran it (``sim``: ``"mujoco"`` or ``"pybullet"``, added
by the runner)."""


def episode_recorder(job: EpisodeJob, agent=None) -> EpisodeRecorder | None:
    """The recorder of ``job``'s episode (writing ``out_dir/replays/<stem>.npz``, see
    :func:`harness.report.paths.replay_stem`), or None when the job records nothing."""
    if job.record == "none" or not job.out_dir:
        return None
    key = job.key_record()
    header = {**key, "run_id": job.run_id, "agent_label": agent_label(job.agent, job.agent_kwargs),
              "scene": job.episode.scene, "instruction": job.episode.instruction}
    path = Path(job.out_dir) / REPLAYS_DIR / f"{replay_stem(key)}.npz"
    return EpisodeRecorder(job.task, header, path, mode=job.record, agent=agent)


def _past_deadline_then_close(what: str) -> None:
    """Past the job's deadline (serial backend), an error is a timeout: an agent that caught the
    timeout interrupt and raised something else in its place is still recorded ``timeout``."""
    try:
        check_deadline(what)
    except BaseException:
        close_cached_envs()
        raise


def run_episode(job: EpisodeJob) -> dict:
    """Run one episode and return its result record (never raises for in-episode errors, a
    ``SystemExit`` of the agent included; lets :class:`~harness.runner.jobs.JobTimeout` and
    ``KeyboardInterrupt`` through after closing the cached environments). ``os._exit`` cannot
    be caught in-process: on the process backend it is recorded as ``failed`` (the worker died).

    With a deadline set (:func:`~harness.runner.jobs.job_deadline`, the serial backend), the
    clock is checked each time the agent's constructor, ``reset`` or ``act`` (and the
    environment's ``reset`` and ``step``) returns, and when the episode raises: past the
    deadline the episode ends as a timeout, whatever the agent caught."""
    t0 = time.perf_counter()
    status, error, metrics, timings, category, extras = "ok", None, {}, {}, None, {}
    recorder = None
    try:
        if job.task not in TASK_RUNNERS:
            raise ValueError(f"task: expected one of {sorted(TASK_RUNNERS)}, got {job.task!r}")
        import_plugins(job.plugins)
        agent = make_agent(job.agent, **job.agent_kwargs)
        check_deadline("the agent's constructor returned")
        recorder = episode_recorder(job, agent)
        metrics, timings, category, extras = TASK_RUNNERS[job.task](job, agent, recorder)
        spec = AGENTS.get(job.agent)
        extras["uses_map"] = bool(spec.uses_map) if spec else None
        if spec is not None and spec.twin_of:
            extras["twin_of"] = spec.twin_of
        extras["privileged"] = bool(getattr(agent, "privileged", False))
        extras["sim"] = _sim_of(job)
    except SystemExit as exc:  # sys.exit() in an agent ends the episode, not the run
        _past_deadline_then_close("the episode called sys.exit()")
        status = "failed"
        error = (f"SystemExit: the episode called sys.exit({exc.code!r}); recorded as failed\n"
                 + "".join(traceback.format_exc(limit=-4)))
        metrics, extras = {"success": False}, _ended_extras(job, status)
        close_cached_envs()
    except Exception as exc:  # the run goes on; the record says what broke
        _past_deadline_then_close(f"the episode raised {type(exc).__name__}")
        status = "failed"
        error = f"{type(exc).__name__}: {exc}\n" + "".join(traceback.format_exc(limit=-4))
        metrics, extras = {"success": False}, _ended_extras(job, status)
        close_cached_envs()  # an environment that raised may be in a bad state
    except BaseException:  # JobTimeout (serial backend), KeyboardInterrupt: clean up, let it through
        close_cached_envs()
        raise
    if recorder is not None:
        written = recorder.finish(status=status, metrics=metrics, error=error, extras=extras)
        t_video = time.perf_counter()
        videos = render_videos_of(written)
        timings = {**timings, "record_s": recorder.seconds, **({"video_s": time.perf_counter() - t_video} if videos else {})}
    timings = {**timings, "wall_s": time.perf_counter() - t0}
    return job_record(
        job, status=status, error=error,
        metrics={k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in metrics.items()},
        timings=timings, category=category, extras=extras,
    )
