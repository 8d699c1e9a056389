"""How long loading (and validating) a scene file takes, and its peak memory, as scenes grow.

    python benchmarks/bench_scene_load.py [--sizes 100 1000 10000] [--repeat 3] [--naive]

Each scene is a table with ``N`` objects laid out on a grid (none overlapping, so every pair
check runs to the end), written with :func:`sim_envs.scenes.format.save_scene` and read back with
:func:`sim_envs.scenes.format.load_scene`. Reported per size: the file size, the best of
``--repeat`` load times, the time of the overlap check alone
(:func:`sim_envs.scenes.overlaps.overlapping_pairs`), and the peak memory Python allocated
during one load (``tracemalloc``). ``--naive`` also times the old pairwise check
(:func:`~sim_envs.scenes.overlaps.overlapping_pairs_naive`) for the sizes up to 1,000 (at
10,000 objects it takes minutes). Target: 10,000 objects in under 2 s.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # this checkout, _machine

from sim_envs.scenes.format import Scene, SceneObject, Table, load_scene, save_scene  # noqa: E402
from sim_envs.scenes.overlaps import overlapping_pairs, overlapping_pairs_naive  # noqa: E402

_KINDS = (("can", "red"), ("mug", "blue"), ("bowl", "green"), ("box", "yellow"))


def grid_scene(n: int, spacing: float = 0.2) -> Scene:
    """A table holding ``n`` objects of 0.1 m on a square grid ``spacing`` apart (no overlaps)."""
    side = math.ceil(math.sqrt(n))
    width = side * spacing
    table = Table((0.0, 0.0, 0.375), (width, width, 0.05))
    objects = []
    for k in range(n):
        r, c = divmod(k, side)
        asset, color = _KINDS[k % len(_KINDS)]
        x, y = -width / 2 + (c + 0.5) * spacing, -width / 2 + (r + 0.5) * spacing
        objects.append(SceneObject(f"obj{k}", f"{color} {asset}", asset, asset, color, (x, y, table.top_z), 0.3 * (k % 5),
                                   (0.1, 0.08, 0.1), (f"a {color} {asset}",)))
    return Scene(f"grid-{n}", "tabletop", 0, table, tuple(objects))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000], help="object counts")
    ap.add_argument("--repeat", type=int, default=3, help="loads per size; the best is reported")
    ap.add_argument("--naive", action="store_true", help="also time the old pairwise check (sizes <= 1000)")
    args = ap.parse_args()
    try:
        from _machine import probe_line

        print(probe_line())
    except Exception as exc:  # noqa: BLE001 - the probe is optional (threadpoolctl)
        print(f"(machine probe unavailable: {exc})")
    print(f"{'objects':>8} {'file MB':>8} {'load s':>8} {'overlap s':>9} {'peak MB':>8}" + (f" {'naive s':>8}" if args.naive else ""))
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            scene = grid_scene(n)
            path = save_scene(scene, Path(tmp) / f"grid-{n}.json")
            loads = []
            for _ in range(args.repeat):
                t = time.perf_counter()
                loaded = load_scene(path)
                loads.append(time.perf_counter() - t)
            assert len(loaded.objects) == n
            t = time.perf_counter()
            pairs = overlapping_pairs(loaded.objects)
            overlap_s = time.perf_counter() - t
            assert not pairs
            tracemalloc.start()
            load_scene(path)
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            row = f"{n:>8} {path.stat().st_size / 1e6:>8.2f} {min(loads):>8.3f} {overlap_s:>9.4f} {peak / 1e6:>8.1f}"
            if args.naive:
                if n <= 1000:
                    t = time.perf_counter()
                    overlapping_pairs_naive(loaded.objects)
                    row += f" {time.perf_counter() - t:>8.2f}"
                else:
                    row += f" {'(skip)':>8}"
            print(row)


if __name__ == "__main__":
    main()
