"""Household scene benchmarks: reset time (generation + MuJoCo build + camera) and render speed.

    python benchmarks/bench_household.py          # v1 apartments, then v2 (library objects)

Targets (2-core CPU, software rasteriser): reset < 2 s; RGB-D + segmentation at 320x240 in a
room sweep as fast as the tabletop scenes (bench_render.py).
"""

from __future__ import annotations

import statistics
import time

from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.gen_household import generate_household
from sim_envs.scenes.gen_household_v2 import generate_household_v2
from sim_envs.scenes.search_episodes_v2 import apartment_seeds
from sim_envs.envs.scene_scan import SceneScanEnv
from sim_envs.scenes.trajectories import room_sweep_trajectory

from bench_render import time_mujoco_renders


def bench_reset(n: int = 10, *, v2: bool = False) -> None:
    """Generation + MuJoCo build + camera; ``v2``: the library-filled apartments on the shipped
    evaluation seeds (library meshes come from the export cache, built on first use)."""
    gen, build, total = [], [], []
    seeds = apartment_seeds()[:n] if v2 else range(n)
    for seed in seeds:
        t0 = time.perf_counter()
        scene = generate_household_v2(seed) if v2 else generate_household(seed)
        t1 = time.perf_counter()
        sim = build_mujoco(scene)
        cam = MujocoRGBDCamera(sim.model, sim.data, 320, 240, geom_object=sim.geom_labels())
        t2 = time.perf_counter()
        cam.close()
        gen.append(t1 - t0)
        build.append(t2 - t1)
        total.append(t2 - t0)
    print(
        f"household{' v2' if v2 else ''} reset (generate + build + camera), {n} seeds: median {1000 * statistics.median(total):.0f} ms, "
        f"max {1000 * max(total):.0f} ms (generate median {1000 * statistics.median(gen):.0f} ms, "
        f"build + camera median {1000 * statistics.median(build):.0f} ms)"
    )


def bench_env_reset(n: int = 5) -> None:
    env = SceneScanEnv(kind="household", num_frames=24)
    times = []
    for seed in range(n):
        t0 = time.perf_counter()
        env.reset(seed=seed)
        times.append(time.perf_counter() - t0)
    env.close()
    print(f"SceneScan(kind='household').reset incl. first frame and scene graph: median {1000 * statistics.median(times):.0f} ms, max {1000 * max(times):.0f} ms")


def bench_render(width: int, height: int, frames: int = 60, segmentation: bool = True, *, v2: bool = False) -> None:
    scene = generate_household_v2(apartment_seeds()[0]) if v2 else generate_household(0)
    time_mujoco_renders("household v2" if v2 else "household", scene, lambda sim: sim.geom_labels(), room_sweep_trajectory(scene, frames), width, height, segmentation)


if __name__ == "__main__":
    bench_reset()
    bench_env_reset()
    bench_render(320, 240)
    bench_render(320, 240, segmentation=False)
    bench_render(640, 480)
    bench_reset(v2=True)
    bench_render(320, 240, v2=True)
    bench_render(320, 240, segmentation=False, v2=True)
