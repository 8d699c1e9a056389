"""The same search episodes in MuJoCo and in PyBullet: success in each and the paired difference.

    python benchmarks/sim_to_sim_search.py                              # oracle-searcher, first 20 sealed search-v2 episodes
    python benchmarks/sim_to_sim_search.py --episodes 10 --agent map-navigator --encoder oracle-open

Each episode of ``search-v2`` (the sealed evaluation searches) runs once in ``search-v2`` (MuJoCo)
and once in ``search-v2-pybullet`` (PyBullet), with the same agent, seed and settings, through
the harness's own episode runner (:func:`harness.runner.tasks.run_episode`), serially. Printed: per
simulator the successes, the paired table (both, MuJoCo only, PyBullet only, neither) and the
difference in success (PyBullet minus MuJoCo, points) with a 95% interval from the paired
differences (normal approximation; with few discordant pairs read the counts, not the interval).
``--json PATH`` also writes every pair.

The privileged ``oracle-searcher`` reads the floor plan and the goal's box, never an image, so
for it the environments render nothing: its pairs test that the two simulators pose the same
problem (base kinematics, collisions, goal boxes, success), not their images.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SUITES = {"mujoco": "search-v2", "pybullet": "search-v2-pybullet"}


def paired(episodes: int, agent: str, encoder: str | None) -> list[dict]:
    """One dict per episode: ``episode_id`` and per simulator ``success``, ``spl``, ``steps``,
    ``wall_s`` and ``status``."""
    from harness.runner.suites import get_suite, suite_encoder, suite_episodes
    from harness.runner.tasks import EpisodeJob, close_cached_envs, run_episode

    rows = []
    try:
        for sim, name in SUITES.items():
            suite = get_suite(name)
            kwargs = {"encoder": suite_encoder(suite, encoder)} if agent != "oracle-searcher" else {}
            for k, ep in enumerate(suite_episodes(suite)[:episodes]):
                job = EpisodeJob(run_id="sim-to-sim", suite=name, task=suite.task, agent=agent, agent_kwargs=kwargs,
                                 episode=ep, env_kwargs=dict(suite.env_kwargs))
                t0 = time.perf_counter()
                rec = run_episode(job)
                if len(rows) <= k:
                    rows.append({"episode_id": ep.episode_id})
                if rows[k]["episode_id"] != ep.episode_id:
                    raise RuntimeError(f"{name}: episode {k} is {ep.episode_id!r}; search-v2 has {rows[k]['episode_id']!r} there")
                m = rec.get("metrics", {})
                rows[k][sim] = {"success": bool(m.get("success")), "spl": float(m.get("spl", 0.0)), "steps": m.get("steps"),
                                "status": rec["status"], "wall_s": round(time.perf_counter() - t0, 2),
                                "recorded_sim": rec.get("extras", {}).get("sim")}
            close_cached_envs()
    finally:
        close_cached_envs()
    return rows


def summary(rows: list[dict]) -> dict:
    """Successes per simulator, the paired table and the difference (points) with its 95% interval."""
    n = len(rows)
    m = [r["mujoco"]["success"] for r in rows]
    q = [r["pybullet"]["success"] for r in rows]
    d = [int(b) - int(a) for a, b in zip(m, q)]
    mean = sum(d) / n if n else 0.0
    var = sum((x - mean) ** 2 for x in d) / (n - 1) if n > 1 else 0.0
    half = 1.96 * math.sqrt(var / n) if n else 0.0
    return {
        "episodes": n, "mujoco_success": sum(m), "pybullet_success": sum(q),
        "both": sum(a and b for a, b in zip(m, q)), "mujoco_only": sum(a and not b for a, b in zip(m, q)),
        "pybullet_only": sum(b and not a for a, b in zip(m, q)), "neither": sum(not a and not b for a, b in zip(m, q)),
        "difference_points": 100 * mean, "interval_points": (100 * (mean - half), 100 * (mean + half)),
        "wall_s": {s: sum(r[s]["wall_s"] for r in rows) for s in SUITES},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=20, help="the first N sealed search-v2 episodes (default 20)")
    ap.add_argument("--agent", default="oracle-searcher", help="agent (default oracle-searcher)")
    ap.add_argument("--encoder", default=None, help="perception of a map agent (default: the suite's)")
    ap.add_argument("--json", type=Path, default=None, help="also write the pairs and the summary here")
    args = ap.parse_args(argv)
    if args.episodes < 1:
        ap.error(f"--episodes: expected at least 1, got {args.episodes}")
    rows = paired(args.episodes, args.agent, args.encoder)
    s = summary(rows)
    print(f"{args.agent}, first {s['episodes']} sealed search-v2 episodes")
    print("| simulator | success | of | wall s |\n|---|---:|---:|---:|")
    for sim in SUITES:
        print(f"| {sim} | {s[f'{sim}_success']} | {s['episodes']} | {s['wall_s'][sim]:.0f} |")
    print(f"paired: both {s['both']}, MuJoCo only {s['mujoco_only']}, PyBullet only {s['pybullet_only']}, neither {s['neither']}")
    lo, hi = s["interval_points"]
    print(f"PyBullet - MuJoCo: {s['difference_points']:+.1f} points (95% interval {lo:+.1f} to {hi:+.1f})")
    bad = [(r["episode_id"], sim, r[sim]["status"]) for r in rows for sim in SUITES if r[sim]["status"] != "ok"]
    if bad:
        print("episodes that did not end ok:", bad)
    if args.json:
        args.json.write_text(json.dumps({"agent": args.agent, "summary": s, "pairs": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
