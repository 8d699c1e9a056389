"""What the language planner costs an instruction episode: CPU of the planner calls and of the map listings.

    python benchmarks/bench_instruct.py                          # 6 development episodes, oracle-open, offline planner
    python benchmarks/bench_instruct.py --episodes 12 --encoder embedded-v2

Runs ``map-planner`` and ``generic-planner`` on the first development instruction episodes
(``instruct-v2``'s calibration set, :func:`harness.runner.develop.development_suite`: never the reported ones) through the harness's own
episode runner, serially, and prints per agent: the episode's process CPU time, the share of it in
the planner's ``propose`` calls (the issue's target: at most 20% with the offline backend), the
share in listing the map's objects for the planner (map context only: the map asked for every
category the planner knows, in one batch), the calls per episode and the process's peak resident
memory. ``--json PATH`` also writes the rows.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

AGENTS = ("map-planner", "generic-planner")


def measure(episodes: int, encoder: str) -> list[dict]:
    """One dict per (agent, episode): CPU seconds, planner and listing seconds, calls, success."""
    from harness.runner.develop import development_suite
    from harness.runner.suites import suite_episodes
    from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode

    suite = development_suite("instruct-v2")
    rows = []
    try:
        for agent in AGENTS:
            for ep in suite_episodes(suite)[:episodes]:
                job = EpisodeJob(run_id="bench-instruct", suite=suite.name, task=suite.task, agent=agent,
                                 agent_kwargs={"encoder": encoder}, episode=ep, env_kwargs=dict(suite.env_kwargs))
                cpu0 = time.process_time()
                rec = run_episode(job)
                cpu = time.process_time() - cpu0
                planner = rec["extras"].get("planner") or {}
                rows.append({"agent": agent, "episode_id": ep.episode_id, "status": rec["status"],
                             "success": bool(rec["metrics"].get("success")), "cpu_s": cpu,
                             "planner_s": float(planner.get("planner_s", 0.0)), "listing_s": float(planner.get("context_s", 0.0)),
                             "calls": int(planner.get("calls", 0))})
    finally:
        close_cached_envs()
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=6)
    ap.add_argument("--encoder", default="oracle-open")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = measure(args.episodes, args.encoder)
    print(f"{'agent':16s} {'episodes':>8s} {'CPU s/ep':>9s} {'planner':>8s} {'listing':>8s} {'calls/ep':>9s} {'success':>8s}")
    for agent in AGENTS:
        mine = [r for r in rows if r["agent"] == agent]
        cpu = sum(r["cpu_s"] for r in mine)
        print(f"{agent:16s} {len(mine):8d} {cpu / len(mine):9.1f} {sum(r['planner_s'] for r in mine) / cpu:8.1%} "
              f"{sum(r['listing_s'] for r in mine) / cpu:8.1%} {sum(r['calls'] for r in mine) / len(mine):9.1f} "
              f"{sum(r['success'] for r in mine):5d}/{len(mine)}")
    print(f"peak resident memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB "
          f"(encoder {args.encoder}, offline planner)")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
