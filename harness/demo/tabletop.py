"""The mapping demo on a simulated tabletop: MuJoCo frames, RGB-D mask proposals, a real encoder.

A procedural tabletop scene (:func:`sim_envs.scenes.gen_tabletop.generate_tabletop`, a seed never
used to train the embedded tower) is rendered along an orbit. Each frame's masks come
from the RGB-D proposer, its features from the encoder (a perceived
:class:`~conceptfusion.perception.featurizer.FrameFeaturizer`), and the
frames are fused into one map. The map is queried with the name of every object on the
table and with one instance name that is absent (chosen among the colour x category names
so that, where possible, neither its category nor its colour is on the table), which must
come back not found.

Ground truth for a query: the map points inside the object's rotated box (1 cm margin).
"""

from __future__ import annotations

import time
from contextlib import closing
from pathlib import Path

import numpy as np

from conceptfusion.map.fusion import PointFusionMap
from harness.demo.scoring import DemoConfig, demo_summary, score_queries

__all__ = ["absent_name", "points_on_object", "run_tabletop_demo"]


def absent_name(present: list[tuple[str, str]], colors: list[str], categories: list[str]) -> str:
    """An instance name ("pink ball") not on the table, preferring an absent category, then an absent colour.

    Args:
        present: (colour, category) of each object on the table.
    """
    cats = {c for _, c in present}
    cols = {c for c, _ in present}
    names = [(cat in cats, col in cols, f"{col} {cat}") for cat in sorted(categories) for col in sorted(colors)
             if (col, cat) not in set(present)]
    if not names:
        raise ValueError("absent_name: every colour x category instance is on the table")
    return min(names)[2]


def points_on_object(points_n3: np.ndarray, obj, *, tol: float = 0.01) -> np.ndarray:
    """Points within ``tol`` metres of an object's rotated box (z from its base up).

    Shape:
        (N, 3) -> (N,) bool.
    """
    p = np.asarray(points_n3, float) - np.asarray(obj.position, float)
    c, s = np.cos(obj.yaw), np.sin(obj.yaw)
    x = c * p[:, 0] + s * p[:, 1]
    y = -s * p[:, 0] + c * p[:, 1]
    sx, sy, sz = (float(v) for v in obj.size)
    return (np.abs(x) <= sx / 2 + tol) & (np.abs(y) <= sy / 2 + tol) & (p[:, 2] >= -tol) & (p[:, 2] <= sz + tol)


def run_tabletop_demo(config: DemoConfig, featurizer, out_dir: Path | None = None) -> dict:
    """Build the map of ``generate_tabletop(config.scene_seed)``, query it, score it (see the module docstring).

    ``featurizer`` is the perception (:func:`conceptfusion.perception.featurizer.make_featurizer`
    of the config's encoder and proposer).

    ``config`` is a :class:`harness.demo.scoring.DemoConfig`; the outcomes are :class:`harness.demo.scoring.QueryOutcome`.
    """
    from sim_envs.assets.objects import ASSETS, COLORS
    from sim_envs.mujoco.scan import iter_views
    from sim_envs.mujoco.scene import build_mujoco
    from sim_envs.scenes.gen_tabletop import generate_tabletop
    from sim_envs.scenes.trajectories import orbit_trajectory

    scene = generate_tabletop(config.scene_seed)
    ms = build_mujoco(scene)
    fmap = PointFusionMap(featurizer.dim)
    t_features = t_fuse = 0.0
    poses = orbit_trajectory(scene, config.frames)
    with closing(iter_views(ms, poses, config.width, config.height, fovy_deg=config.fovy_deg)) as frames:
        for f in frames:
            t0 = time.perf_counter()
            feats = featurizer.features(f)
            t1 = time.perf_counter()
            fmap.integrate(f.rgb, f.depth, f.K, f.cam_to_world, feats)
            t_fuse += time.perf_counter() - t1
            t_features += t1 - t0
    present = [(o.color, o.category) for o in scene.objects]
    absent = absent_name(present, list(COLORS), sorted({a.category for a in ASSETS.values()}))
    queries = sorted(o.name for o in scene.objects) + [absent]
    points = fmap.points
    truths = {}
    for text in queries:
        obj = next((o for o in scene.objects if o.name == text), None)
        centre = None if obj is None else np.asarray(obj.position, float) + np.array([0.0, 0.0, obj.size[2] / 2])
        truths[text] = None if obj is None else (obj.name, centre, points_on_object(points, obj))
    return demo_summary(scene.id, fmap, config.frames, t_features, t_fuse, score_queries(fmap, featurizer.encoder, truths, out_dir, config))
