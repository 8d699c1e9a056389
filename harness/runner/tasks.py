"""Episode rollouts per task: build the environment, run an agent through one episode, score it.

This is the only place that joins an environment and an agent. :class:`EpisodeJob` is a
:class:`~harness.runner.jobs.Job`: picklable, and ``job.run()`` (or :func:`run_episode`) returns
its result record (see :mod:`harness.runner.results`). It never raises for what happens inside
the episode: an exception becomes ``status="failed"`` with the error, so a broken agent cannot
stop a run.
"""

from __future__ import annotations

import time
import traceback
import zlib
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from agents.registry import AGENTS, make_agent
from harness.runner.jobs import import_plugins, job_record
from harness.runner.results import agent_label
from sim_envs.scenes.episodes import Episode

__all__ = ["EpisodeJob", "run_episode", "episode_seed", "TASK_RUNNERS", "close_cached_envs"]


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

    @property
    def encoder(self) -> str:
        return str(self.agent_kwargs.get("encoder", "none"))

    @property
    def label(self) -> str:
        return f"{agent_label(self.agent, self.agent_kwargs)} {self.episode.episode_id}"

    def key_record(self) -> dict:
        """The fields that identify this episode's record (see :func:`harness.runner.results.record_key`)."""
        return {"suite": self.suite, "agent": self.agent, "agent_kwargs": dict(self.agent_kwargs), "encoder": self.encoder,
                "episode_id": self.episode.episode_id, "seed": self.seed}

    def run(self) -> list[dict]:
        """Run the episode: its one record (see :func:`run_episode`)."""
        return [run_episode(self)]

    def failure_record(self, status: str, error: str, wall_s: float) -> dict:
        """The record of the episode when its worker timed out or died."""
        return job_record(self, status=status, error=error, metrics={"success": False}, timings={"wall_s": wall_s})


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


def _search_env(kwargs: dict):
    from sim_envs.envs.object_search import ObjectSearchEnv

    return ObjectSearchEnv(**kwargs)


def _rearrange_env(kwargs: dict):
    from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv

    return TabletopRearrangeEnv(**kwargs)


def _rollout(env, agent, job: EpisodeJob, *, on_step: Callable[[dict, dict], None] | None = None):
    t_env = t_agent = 0.0
    t0 = time.perf_counter()
    obs, info = env.reset(seed=job.seed, options={"episode": job.episode})
    t_env += time.perf_counter() - t0
    agent.reset(seed=episode_seed(job))
    privileged = bool(getattr(agent, "privileged", False))
    if on_step:
        on_step(obs, info)
    steps = 0
    while True:
        t0 = time.perf_counter()
        action = agent.act(obs, info if privileged else None)
        t1 = time.perf_counter()
        obs, reward, terminated, truncated, info = env.step(action)
        t2 = time.perf_counter()
        t_agent += t1 - t0
        t_env += t2 - t1
        steps += 1
        if on_step:
            on_step(obs, info)
        if terminated or truncated:
            return info, steps, {"env_s": t_env, "agent_s": t_agent}


def _run_search(job: EpisodeJob, agent) -> tuple[dict, dict, str | None, dict]:
    env = _cached_env(("object_search", tuple(sorted(job.env_kwargs.items()))), lambda: _search_env(job.env_kwargs))
    path: list[list[float]] = []
    info, steps, timings = _rollout(env, agent, job, on_step=lambda o, i: path.append([round(float(v), 3) for v in o["base_pose"][:2]]))
    box = env.unwrapped.goal_box
    goal = env.unwrapped.scene.object(job.episode.goals[0].object_id)
    metrics = {
        "success": bool(info["success"]), "spl": float(info["spl"]), "distance_to_goal": float(info["distance_to_goal"]),
        "steps": int(info["steps"]), "collisions": int(info["collisions"]), "path_length": float(info["path_length"]),
        "shortest_path_length": float(info["shortest_path_length"]),
    }
    extras = {
        "path_xy": path, "start_xy": path[0] if path else None,
        "goal_xy": [round(float(v), 3) for v in (box[0, :2] + box[1, :2]) / 2], "scene": job.episode.scene,
    }
    return metrics, timings, goal.category, extras


def _run_rearrange(job: EpisodeJob, agent) -> tuple[dict, dict, str | None, dict]:
    env = _cached_env(("tabletop_rearrange", tuple(sorted(job.env_kwargs.items()))), lambda: _rearrange_env(job.env_kwargs))
    info, steps, timings = _rollout(env, agent, job)
    ev = info.get("evaluation", {})
    scene = env.unwrapped.sim.scene
    category = scene.object(job.episode.goals[0].object_id).category if job.episode.goals else None
    metrics = {"success": bool(info["success"]), "steps": int(info["steps"])}
    for key in ("targets_on_side", "max_distractor_shift", "targets_done_fraction"):
        if isinstance(ev.get(key), (int, float, bool)):
            metrics[key] = ev[key]
    return metrics, timings, category, {"scene": job.episode.scene}


TASK_RUNNERS: dict[str, Callable[[EpisodeJob, Any], tuple[dict, dict, str | None, dict]]] = {
    "object_search": _run_search,
    "tabletop_rearrange": _run_rearrange,
}
"""Per task: (job, agent) -> (metrics, timings, goal category, extras)."""


def run_episode(job: EpisodeJob) -> dict:
    """Run one episode and return its result record (never raises for in-episode errors, a
    ``SystemExit`` of the agent included; lets :class:`~harness.runner.jobs.JobTimeout` and
    ``KeyboardInterrupt`` through after closing the cached environments). ``os._exit`` cannot
    be caught in-process: on the process backend it is recorded as ``failed`` (the worker died)."""
    t0 = time.perf_counter()
    status, error, metrics, timings, category, extras = "ok", None, {}, {}, None, {}
    try:
        if job.task not in TASK_RUNNERS:
            raise ValueError(f"task: expected one of {sorted(TASK_RUNNERS)}, got {job.task!r}")
        import_plugins(job.plugins)
        agent = make_agent(job.agent, **job.agent_kwargs)
        metrics, timings, category, extras = TASK_RUNNERS[job.task](job, agent)
        spec = AGENTS.get(job.agent)
        extras["uses_map"] = bool(spec.uses_map) if spec else None
        extras["privileged"] = bool(getattr(agent, "privileged", False))
    except SystemExit as exc:  # sys.exit() in an agent ends the episode, not the run
        status = "failed"
        error = (f"SystemExit: the episode called sys.exit({exc.code!r}); recorded as failed\n"
                 + "".join(traceback.format_exc(limit=-4)))
        metrics = {"success": False}
        close_cached_envs()
    except Exception as exc:  # the run goes on; the record says what broke
        status = "failed"
        error = f"{type(exc).__name__}: {exc}\n" + "".join(traceback.format_exc(limit=-4))
        metrics = {"success": False}
        close_cached_envs()  # an environment that raised may be in a bad state
    except BaseException:  # JobTimeout (serial backend), KeyboardInterrupt: clean up, let it through
        close_cached_envs()
        raise
    timings = {**timings, "wall_s": time.perf_counter() - t0}
    return job_record(
        job, status=status, error=error,
        metrics={k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in metrics.items()},
        timings=timings, category=category, extras=extras,
    )
