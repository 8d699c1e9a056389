"""Rendering and reset benchmarks for the MuJoCo scenes.

    python benchmarks/bench_render.py

Target (2-core CPU, software rasteriser): RGB-D + segmentation at 320x240 >= 100 frames/s.
"""

from __future__ import annotations

import statistics
import time

from sim_envs.mujoco_camera import MujocoRGBDCamera
from sim_envs.mujoco_scene import build_mujoco
from sim_envs.scene_gen import generate_tabletop
from sim_envs.scene_scan import orbit_trajectory


def bench(width: int, height: int, frames: int = 60, segmentation: bool = True) -> None:
    scene = generate_tabletop(0)
    sim = build_mujoco(scene)
    cam = MujocoRGBDCamera(sim.model, sim.data, width, height, geom_object=sim.geom_object)
    poses = orbit_trajectory(scene, frames)
    cam.set_pose(*poses[0])
    cam.render(segmentation=segmentation)
    t0 = time.perf_counter()
    for eye, target in poses:
        cam.set_pose(eye, target)
        cam.render(segmentation=segmentation)
    dt = time.perf_counter() - t0
    what = "RGB-D + segmentation" if segmentation else "RGB-D"
    print(f"MuJoCo {what} {width}x{height}: {frames / dt:.0f} frames/s ({1000 * dt / frames:.1f} ms/frame)")
    cam.close()


def bench_reset(n: int = 10) -> None:
    times = []
    for seed in range(n):
        t0 = time.perf_counter()
        sim = build_mujoco(generate_tabletop(seed))
        cam = MujocoRGBDCamera(sim.model, sim.data, 320, 240, geom_object=sim.geom_object)
        times.append(time.perf_counter() - t0)
        cam.close()
    print(f"tabletop scene build + camera: median {1000 * statistics.median(times):.0f} ms, max {1000 * max(times):.0f} ms")


if __name__ == "__main__":
    bench(320, 240)
    bench(640, 480)
    bench(320, 240, segmentation=False)
    bench(640, 480, segmentation=False)
    bench_reset()
