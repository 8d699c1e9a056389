"""Navigation planning benchmark on an apartment-like grid.

    python benchmarks/bench_plan.py [--pairs 20] [--planner rrtconnect] [--seed 0]

Scene: a 10 m x 10 m apartment at 5 cm resolution (200 x 200 cells): outer walls, five rooms
joined by 0.9 m doorways, furniture boxes, rasterised from a synthetic point cloud (walls and
furniture sampled every 2.5 cm, floor every 5 cm). The base is a 0.2 m disc.

Target (2-core CPU): one navigation episode (goal choice next to an object + path) under 1 s,
median over start/goal pairs. Reports each stage separately: grid from points, inflation, goal
choice (reachable cell next to an object), planning; and, per query, how many needed OMPL
(the straight segment was blocked).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from planners.occupancy import GridConfig, build_occupancy_grid, free_components, reachable_goal_near
from planners.ompl_2d import BasePlannerConfig, plan_base_path
from planners.raycast import path_blocked_segments

RES = 0.05
ROBOT_RADIUS = 0.2


def _box_points(x0: float, y0: float, x1: float, y1: float, z1: float, step: float = 0.025) -> np.ndarray:
    xs = np.arange(x0, x1 + 1e-9, step)
    ys = np.arange(y0, y1 + 1e-9, step)
    zs = np.arange(0.0, z1 + 1e-9, 0.1)
    gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)


def _wall(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """A 5 cm thick, 2.4 m high wall between two points on an axis-aligned line."""
    return _box_points(min(x0, x1) - 0.025, min(y0, y1) - 0.025, max(x0, x1) + 0.025, max(y0, y1) + 0.025, 2.4)


def apartment_points() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The apartment cloud (world frame, z up) and each furniture item's footprint points.

    Shape:
        returns: ((N, 3) points, {name: (M, 2) footprint x, y}).
    """
    parts = []
    fx, fy = np.meshgrid(np.arange(0.0, 10.0, RES), np.arange(0.0, 10.0, RES))
    parts.append(np.stack([fx.ravel(), fy.ravel(), np.zeros(fx.size)], axis=1))
    # Outer walls.
    parts += [_wall(0, 0, 10, 0), _wall(0, 10, 10, 10), _wall(0, 0, 0, 10), _wall(10, 0, 10, 10)]
    # A corridor wall at y = 4 with doorways at x in [1.5, 2.4], [5.5, 6.4] and [8.3, 9.2].
    parts += [_wall(0, 4, 1.5, 4), _wall(2.4, 4, 5.5, 4), _wall(6.4, 4, 8.3, 4), _wall(9.2, 4, 10, 4)]
    # Room dividers above the corridor wall, each with a doorway.
    parts += [_wall(4, 4, 4, 7.0), _wall(4, 7.9, 4, 10)]
    parts += [_wall(7, 4, 7, 5.5), _wall(7, 6.4, 7, 10)]
    # Below the corridor wall: a divider at x = 5 with a doorway at y in [1.0, 1.9].
    parts += [_wall(5, 0, 5, 1.0), _wall(5, 1.9, 5, 4)]
    furniture = {
        "sofa": (0.5, 8.6, 2.6, 9.5, 0.8),
        "table": (5.0, 7.5, 6.2, 8.5, 0.75),
        "bed": (7.6, 7.0, 9.6, 9.6, 0.6),
        "counter": (0.2, 0.2, 3.5, 0.8, 0.9),
        "desk": (7.5, 0.3, 9.5, 1.0, 0.75),
        "armchair": (2.5, 5.5, 3.3, 6.3, 0.9),
    }
    footprints = {}
    for name, (x0, y0, x1, y1, z1) in furniture.items():
        box = _box_points(x0, y0, x1, y1, z1)
        parts.append(box)
        footprints[name] = box[:, :2]
    return np.concatenate(parts), footprints


def _ms(values: list[float]) -> str:
    arr = np.array(values) * 1e3
    return f"median {np.median(arr):7.2f} ms  p90 {np.percentile(arr, 90):7.2f} ms  max {arr.max():7.2f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pairs", type=int, default=20, help="start/goal pairs to plan")
    parser.add_argument("--planner", default="rrtconnect", help="planner name from planners.PLANNERS")
    parser.add_argument("--seed", type=int, default=0, help="seed for the pairs and the planner")
    args = parser.parse_args()

    points, footprints = apartment_points()
    build_occupancy_grid(points[:10], GridConfig(resolution=RES))  # the compiled rasteriser loads on first use
    t0 = time.perf_counter()
    grid = build_occupancy_grid(points, GridConfig(resolution=RES), bounds_xy=(-0.1, -0.1, 10.1, 10.1))
    t_grid = time.perf_counter() - t0
    t0 = time.perf_counter()
    inflated = grid.inflate(ROBOT_RADIUS + RES / 2)
    t_inflate = time.perf_counter() - t0
    h, w = grid.shape
    print(f"apartment: {len(points):,} points -> {h} x {w} grid at {RES} m; robot radius {ROBOT_RADIUS} m")
    print(f"grid from points: {t_grid * 1e3:.1f} ms   inflation: {t_inflate * 1e3:.1f} ms")

    labels, count = free_components(~inflated.occupied_hw)
    sizes = np.bincount(labels.ravel())[1:]
    main_label = int(np.argmax(sizes)) + 1
    cells = np.argwhere(labels == main_label)
    print(f"free space: {count} components, the largest holds {sizes.max():,} cells ({sizes.max() * RES**2:.1f} m^2)")

    rng = np.random.default_rng(args.seed)
    config = BasePlannerConfig(planner=args.planner, time_limit=2.0)
    names = list(footprints)
    plan_times, goal_times, episode_times, statuses, ompl_used, ratios = [], [], [], [], 0, []
    for i in range(args.pairs):
        start = inflated.cell_to_world(cells[rng.integers(len(cells))])
        target = names[i % len(names)]
        t0 = time.perf_counter()
        goal = reachable_goal_near(inflated, start, footprints[target], standoff=ROBOT_RADIUS + 0.3)
        t_goal = time.perf_counter() - t0
        if goal is None:
            statuses.append("no_goal")
            continue
        t1 = time.perf_counter()
        result = plan_base_path(inflated, start, goal, config, seed=args.seed + i)
        t_plan = time.perf_counter() - t1
        statuses.append(result.status)
        goal_times.append(t_goal)
        plan_times.append(t_plan)
        episode_times.append(t_goal + t_plan)
        if result.solved:
            if path_blocked_segments(inflated, result.path).any():
                raise RuntimeError(f"pair {i}: the returned path crosses a blocked cell")
            ratios.append(result.length / max(np.linalg.norm(goal - start), 1e-9))
            ompl_used += result.planner != "straight"

    print(f"\n{args.pairs} episodes with {args.planner} (goal next to a furniture item, then a path):")
    print("  statuses: " + ", ".join(f"{s}={statuses.count(s)}" for s in sorted(set(statuses))))
    print(f"  OMPL needed (straight segment blocked): {ompl_used} of {len(ratios)} solved")
    print(f"  goal choice: {_ms(goal_times)}")
    print(f"  planning:    {_ms(plan_times)}")
    print(f"  episode:     {_ms(episode_times)}   (target: median < 1000 ms)")
    if ratios:
        print(f"  path length / straight-line distance: median {statistics.median(ratios):.2f}, max {max(ratios):.2f}")


if __name__ == "__main__":
    main()
