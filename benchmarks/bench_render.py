"""Rendering, reset and push benchmarks for the MuJoCo and PyBullet scenes.

    python benchmarks/bench_render.py

Target (2-core CPU, software rasteriser): MuJoCo RGB-D + segmentation at 320x240 >= 100 frames/s.
PyBullet: its tiny renderer and the EGL plugin (llvmpipe here), and the Panda push primitive.
"""

from __future__ import annotations

import itertools
import statistics
import time

import math

from sim_envs.mujoco.camera import MujocoRGBDCamera
from sim_envs.mujoco.scan import iter_views
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.trajectories import orbit_trajectory


def time_mujoco_renders(label: str, scene, geom_object, poses, width: int, height: int, segmentation: bool = True) -> float:
    """Render ``poses`` (after one warm-up frame) with a MuJoCo camera, print and return frames/s."""
    sim = build_mujoco(scene)
    frames = iter_views(sim, [poses[0], *poses], width, height, geom_labels=geom_object(sim), segmentation=segmentation)
    next(frames)  # warm-up: the camera and one frame
    t0 = time.perf_counter()
    for _ in itertools.islice(frames, len(poses)):  # stop before the camera is released
        pass
    dt = time.perf_counter() - t0
    frames.close()
    what = "RGB-D + segmentation" if segmentation else "RGB-D"
    print(f"{label} {what} {width}x{height}: {len(poses) / dt:.0f} frames/s ({1000 * dt / len(poses):.1f} ms/frame)")
    return len(poses) / dt


def bench(width: int, height: int, frames: int = 60, segmentation: bool = True) -> None:
    scene = generate_tabletop(0)
    time_mujoco_renders("MuJoCo", scene, lambda sim: sim.geom_object, orbit_trajectory(scene, frames), width, height, segmentation)


def bench_reset(n: int = 10) -> None:
    times = []
    for seed in range(n):
        t0 = time.perf_counter()
        sim = build_mujoco(generate_tabletop(seed))
        cam = MujocoRGBDCamera(sim.model, sim.data, 320, 240, geom_object=sim.geom_object)
        times.append(time.perf_counter() - t0)
        cam.close()
    print(f"tabletop scene build + camera: median {1000 * statistics.median(times):.0f} ms, max {1000 * max(times):.0f} ms")


def bench_pybullet(width: int, height: int, renderer: str, frames: int = 20) -> None:
    from sim_envs.pybullet.tabletop import PyBulletTabletop

    scene = generate_tabletop(0)
    sim = PyBulletTabletop(scene, renderer=renderer)
    poses = orbit_trajectory(scene, frames)
    sim.render(*poses[0], width, height)
    used = next(iter(sim._cameras.values())).renderer
    t0 = time.perf_counter()
    for eye, target in poses:
        sim.render(eye, target, width, height)
    dt = time.perf_counter() - t0
    print(f"PyBullet {used} RGB-D + segmentation {width}x{height}: {frames / dt:.1f} frames/s ({1000 * dt / frames:.0f} ms/frame)")
    sim.close()


def bench_push(n: int = 6) -> None:
    from sim_envs.pybullet.tabletop import PyBulletTabletop

    scene = generate_tabletop(0)
    t0 = time.perf_counter()
    sim = PyBulletTabletop(scene, renderer="tiny")
    build = time.perf_counter() - t0
    times, refused = [], 0
    for k in range(n):  # pushes through each object's centre, from 8 cm before it
        o = scene.objects[k % len(scene.objects)]
        yaw = math.pi / 2 + 0.4 * (k % 3 - 1)
        start = (o.position[0] - 0.08 * math.cos(yaw) - 0.5 * o.size[0] * math.cos(yaw), o.position[1] - 0.08 * math.sin(yaw) - 0.5 * o.size[1] * math.sin(yaw))
        t0 = time.perf_counter()
        out = sim.push(start, yaw, 0.12)
        if out.executed:
            times.append(time.perf_counter() - t0)
        else:
            refused += 1
    sim.close()
    med = 1000 * statistics.median(times) if times else float("nan")
    print(f"PyBullet Panda tabletop build {1000 * build:.0f} ms; push (12 cm, incl. transit and settling): median {med:.0f} ms over {len(times)} pushes ({refused} refused)")


if __name__ == "__main__":
    bench(320, 240)
    bench(640, 480)
    bench(320, 240, segmentation=False)
    bench(640, 480, segmentation=False)
    bench_reset()
    for renderer in ("tiny", "egl"):
        bench_pybullet(320, 240, renderer)
        bench_pybullet(640, 480, renderer)
    bench_push()
