"""The privileged oracle pusher on the shipped tabletop episodes: success rate and time per episode.

    python benchmarks/bench_tabletop_oracle.py [--backend mujoco] [--episodes v1|v2|FILE] [--limit N] [--width 160 --height 120]

The oracle proves the episodes solvable with the push primitive; target: > 90% success (v2: on
both backends). ``--episodes`` takes ``v1`` (``scenes/tabletop/episodes-v1.jsonl``, the
default), ``v2`` (``scenes/tabletop-v2/episodes-v2.jsonl``) or any episode file; episodes that
record a description kind are also scored per kind.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import time

import numpy as np

from agents.oracle_push import OraclePushAgent
from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes
from sim_envs.envs.tabletop_rearrange import TabletopRearrangeEnv


SHIPPED = {"v1": str(SCENES_ROOT / "tabletop" / "episodes-v1.jsonl"), "v2": str(SCENES_ROOT / "tabletop-v2" / "episodes-v2.jsonl")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="mujoco")
    ap.add_argument("--episodes", default="v1", help="v1, v2 or an episode file")
    ap.add_argument("--limit", type=int, default=0, help="only the first N episodes (0: all)")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    args = ap.parse_args()
    path = SHIPPED.get(args.episodes, args.episodes)
    episodes = load_episodes(path)
    env = TabletopRearrangeEnv(backend=args.backend, episodes=episodes, width=args.width, height=args.height)
    agent = OraclePushAgent()
    n = len(episodes.episodes) if args.limit <= 0 else min(args.limit, len(episodes.episodes))
    wins, times, steps, failed = 0, [], [], []
    by_kind: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    for i in range(n):
        t0 = time.perf_counter()
        obs, info = env.reset(seed=i, options={"episode_index": i})
        agent.reset(seed=i)
        done, reward = False, 0.0
        while not done:
            obs, reward, terminated, truncated, info = env.step(agent.act(obs, info))
            done = terminated or truncated
        times.append(time.perf_counter() - t0)
        steps.append(info["steps"])
        wins += int(reward > 0)
        kind = episodes.episodes[i].description_kind
        if kind is not None:
            by_kind[kind][0] += int(reward > 0)
            by_kind[kind][1] += 1
        if reward <= 0:
            failed.append((info["episode_id"], info["evaluation"]))
    env.close()
    print(f"oracle on {n} episodes of {path} ({args.backend}, {args.width}x{args.height}): success {wins}/{n} = {100 * wins / n:.1f}%")
    for kind, (w, k) in sorted(by_kind.items()):
        print(f"  described by {kind}: {w}/{k}")
    print(f"time per episode: mean {statistics.mean(times):.2f} s, max {max(times):.2f} s; steps per episode: mean {np.mean(steps):.2f}")
    for ep, ev in failed:
        print(f"  failed {ep}: {ev}")


if __name__ == "__main__":
    main()
