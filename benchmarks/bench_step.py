"""Where an episode step's time goes: render, proposals, encoder, mixing, fusion, query,
planning, control, for `map-navigator` (object search) and `map-pusher` (rearrangement).

    python benchmarks/bench_step.py                       # 2 search + 3 rearrangement episodes, embedded
    python benchmarks/bench_step.py --encoder oracle --search 1 --rearrange 2
    python benchmarks/bench_step.py --rearrange 0 --search-option keyframe_move=0.3 --search-option keyframe_turn_deg=20
    python benchmarks/bench_step.py --world v2            # search-v2 and rearrange-v2 episodes, embedded-v2
    python benchmarks/bench_step.py --world v2 --search 1 --rearrange 0 --sim both   # a search step, MuJoCo against PyBullet

Each component is timed exclusively (a call inside another timed call counts for the inner one
only) by wrapping the functions the agents and environments call:

| component | what is timed |
|---|---|
| render | the environment's step (simulation, collision checks and the RGB-D render) and reset |

``--sim pybullet`` runs the search episodes in PyBullet (the environment's ``backend``), ``--sim
both`` in each simulator in turn, and prints the PyBullet step's ratio to the MuJoCo step.
Rearrangement always runs in MuJoCo here.
| proposals | the mask proposer (`propose`) |
| encoder | image embeddings (`encode_image`) and text embeddings (`encode_text`) |
| mixing | the rest of the pixel features (eqs. 3-6, the palette) |
| fusion | `PointFusionMap.integrate` |
| query | `locate` (scores, relevancy, regions, the score floor) |
| planning | occupancy grids, frontiers, OMPL base plans, path checks, push plans |
| control | pure pursuit |
| other | the rest of the agent's `act` |

Figures are per step (mean over the episodes' steps) and per episode, in wall time and in process
CPU time; the machine's load changes wall time far more than CPU time, so compare CPU figures
between runs on a shared machine and run it on an idle machine for published wall figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict
from contextlib import ExitStack
from pathlib import Path
from unittest import mock

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

COMPONENTS = ("render", "proposals", "encoder", "mixing", "fusion", "query", "planning", "control", "other")


class ExclusiveTimer:
    """Exclusive wall time and process CPU time per component over nested timed calls.

    CPU time (``time.process_time``: every thread of the process, onnxruntime's and the
    renderer's included) moves far less than wall time with the machine's load, so it is the
    figure to compare between runs on a shared machine.
    """

    def __init__(self) -> None:
        self.total: dict[str, float] = defaultdict(float)
        self.cpu: dict[str, float] = defaultdict(float)
        self._stack: list[list] = []

    def wrap(self, component: str, fn):
        def timed(*args, **kwargs):
            frame = [component, 0.0, 0.0]
            self._stack.append(frame)
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                dt, dc = time.perf_counter() - t0, time.process_time() - c0
                self._stack.pop()
                self.total[component] += dt - frame[1]
                self.cpu[component] += dc - frame[2]
                if self._stack:
                    self._stack[-1][1] += dt
                    self._stack[-1][2] += dc
        timed.__wrapped__ = fn
        return timed


def _patches(timer: ExclusiveTimer, agent) -> list:
    """mock.patch objects wrapping every timed function (module attributes the agents look up)."""
    import agents.navigator as nav
    import agents.pusher as push
    from agents.concept_map import ConceptMapper
    from conceptfusion.map.fusion import PointFusionMap

    out = []

    def attr(target, name, component):
        out.append(mock.patch.object(target, name, timer.wrap(component, getattr(target, name))))

    for name in ("build_occupancy_grid", "nearest_free_cell", "reachable_goal_near", "plan_base_path", "check_path_blocked",
                 "find_frontiers", "choose_frontier"):
        attr(nav, name, "planning")
    attr(nav, "pure_pursuit_step", "control")
    attr(push, "plan_push", "planning")
    attr(PointFusionMap, "integrate", "fusion")
    attr(ConceptMapper, "locate", "query")
    featurizer = agent.mapper.featurizer
    attr(type(featurizer), "features", "mixing")
    proposer = getattr(featurizer, "proposer", None)
    if proposer is not None:
        attr(type(proposer), "propose", "proposals")
    enc = featurizer.encoder
    for name in ("encode_image", "encode_text"):
        if hasattr(type(enc), name):
            attr(type(enc), name, "encoder")
    return out


SUITE_OF = {("search", "v1"): "search", ("rearrange", "v1"): "rearrange", ("search", "v2"): "search-v2",
            ("rearrange", "v2"): "rearrange-v2"}
"""(task, world) -> the suite whose episodes and environment settings (camera, scan) are timed."""


def run(task: str, agent_name: str, encoder: str, episodes: int, options: dict | None = None, world: str = "v1",
        sim: str = "mujoco") -> dict:
    """Roll the first ``episodes`` episodes of the shipped ``world`` suite of ``task`` with a timed
    agent (``options``: extra agent options, e.g. ``{"keyframe_move": 0.3}``) in simulator ``sim``
    (search only)."""
    from agents.registry import make_agent
    from harness.runner.tasks import env_kwargs_for
    from sim_envs.envs.object_search import ObjectSearchEnv
    from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv
    from harness.runner.suites import SUITES
    from sim_envs.scenes.episodes import load_episodes

    suite = SUITES[SUITE_OF[(task, world)]]
    eps = load_episodes(suite.episodes_file).episodes[:episodes]
    agent = make_agent(agent_name, encoder=encoder, **(options or {}))
    # As the harness builds them: the ground-truth segmentation pass only for a privileged
    # agent, the orbit scan only for an agent that reads it.
    if task == "search":
        env = ObjectSearchEnv(**env_kwargs_for("object_search", {**suite.env_kwargs, "backend": sim}, agent))
    else:
        env = TabletopRearrangeEnv(**env_kwargs_for("tabletop_rearrange", suite.env_kwargs, agent))
    timer = ExclusiveTimer()
    steps, walls, successes = 0, [], 0
    with ExitStack() as stack:
        from harness.runner.jobs import one_blas_thread

        stack.enter_context(one_blas_thread())  # as every harness job runs
        for p in _patches(timer, agent):
            stack.enter_context(p)
        env_step = timer.wrap("render", env.step)
        env_reset = timer.wrap("render", env.reset)
        act = timer.wrap("other", agent.act)
        for k, ep in enumerate(eps):
            t0 = time.perf_counter()
            obs, info = env_reset(seed=0, options={"episode": ep})
            agent.reset(seed=k)
            while True:
                action = act(obs, info if agent.privileged else None)
                obs, _, terminated, truncated, info = env_step(action)
                steps += 1
                if terminated or truncated:
                    break
            walls.append(time.perf_counter() - t0)
            successes += bool(info.get("success"))
    env.close()
    total = sum(walls)
    return {"task": f"{task} {world}" + (f" {sim}" if task == "search" else ""), "agent": agent_name, "sim": sim, "options": dict(options or {}), "encoder": encoder, "episodes": len(eps), "steps": steps,
            "successes": successes, "wall_s": total, "cpu_s": sum(timer.cpu.values()),
            "per_component_s": {c: timer.total.get(c, 0.0) for c in COMPONENTS},
            "per_component_cpu_s": {c: timer.cpu.get(c, 0.0) for c in COMPONENTS}}


def report(r: dict) -> None:
    steps, eps = max(r["steps"], 1), max(r["episodes"], 1)
    opts = ",".join(f"{k}={v}" for k, v in r["options"].items())
    print(f"\n{r['agent']}{f'[{opts}]' if opts else ''} ({r['task']}, {r['encoder']}): {r['episodes']} episodes, {r['steps']} steps, "
          f"{r['successes']} successes; {r['wall_s'] / eps:.2f} s per episode, {1000 * r['wall_s'] / steps:.1f} ms per step "
          f"(CPU {r['cpu_s'] / eps:.2f} s per episode, {1000 * r['cpu_s'] / steps:.1f} ms per step)")
    print("| component | ms per step | s per episode | share | CPU ms per step | CPU share |\n|---|---:|---:|---:|---:|---:|")
    for c in COMPONENTS:
        v, u = r["per_component_s"][c], r["per_component_cpu_s"][c]
        print(f"| {c} | {1000 * v / steps:.1f} | {v / eps:.2f} | {100 * v / max(r['wall_s'], 1e-9):.0f}% "
              f"| {1000 * u / steps:.1f} | {100 * u / max(r['cpu_s'], 1e-9):.0f}% |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", choices=("v1", "v2"), default="v1",
                        help="v1: the shipped v1 suites (default); v2: search-v2 and rearrange-v2 episodes")
    parser.add_argument("--encoder", default=None, help="perception (default: embedded for v1, embedded-v2 for v2)")
    parser.add_argument("--search", type=int, default=2, help="search episodes (map-navigator)")
    parser.add_argument("--rearrange", type=int, default=3, help="rearrangement episodes (map-pusher)")
    parser.add_argument("--sim", choices=("mujoco", "pybullet", "both"), default="mujoco",
                        help="simulator of the search episodes (both: each in turn, then the ratio)")
    parser.add_argument("--search-option", action="append", default=[], metavar="KEY=VALUE",
                        help="a map-navigator option, e.g. keyframe_move=0.3 (repeatable)")
    args = parser.parse_args(argv)
    options = {}
    for item in args.search_option:
        key, sep, value = item.partition("=")
        if not sep:
            parser.error(f"--search-option: expected KEY=VALUE, got {item!r}")
        options[key.strip()] = value.strip()
    from benchmarks._machine import probe_line

    print(probe_line())
    encoder = args.encoder or {"v1": "embedded", "v2": "embedded-v2"}[args.world]
    if args.search:
        sims = ("mujoco", "pybullet") if args.sim == "both" else (args.sim,)
        results = {sim: run("search", "map-navigator", encoder, args.search, options, args.world, sim) for sim in sims}
        for r in results.values():
            report(r)
        if len(results) == 2:
            per = {k: (r["wall_s"] / max(r["steps"], 1), r["cpu_s"] / max(r["steps"], 1)) for k, r in results.items()}
            render = {k: r["per_component_cpu_s"]["render"] / max(r["steps"], 1) for k, r in results.items()}
            # The agent drives differently in each simulator (other frames, other keyframes), so
            # the whole steps are not the same work; swapping the render alone compares like for like.
            same_steps = per["pybullet"][1] / max(per["pybullet"][1] - render["pybullet"] + render["mujoco"], 1e-9)
            print(f"\nrender CPU per step: MuJoCo {1000 * render['mujoco']:.1f} ms ({100 * render['mujoco'] / per['mujoco'][1]:.0f}% "
                  f"of its step), PyBullet {1000 * render['pybullet']:.1f} ms ({100 * render['pybullet'] / per['pybullet'][1]:.0f}%)")
            print(f"PyBullet step / MuJoCo step: whole episodes CPU {per['pybullet'][1] / per['mujoco'][1]:.2f}x (different "
                  f"trajectories); the PyBullet episode's steps with MuJoCo's render instead: {same_steps:.2f}x (target at most 1.5x)")
    if args.rearrange:
        report(run("rearrange", "map-pusher", encoder, args.rearrange, world=args.world))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
