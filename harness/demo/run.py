"""The mapping demo: fuse rendered RGB-D frames into a map, query it, score the answers.

Two scenes, chosen by the encoder:

* ``encoder="embedded"`` (default) and any other image-language encoder: a simulated
  MuJoCo tabletop (:mod:`harness.demo.tabletop`), RGB-D mask proposals, queries by object
  name ("red mug") plus one absent object.
* ``encoder="color"``: the simulator-free box scene. Frames come from
  :mod:`conceptfusion.synthetic` (exact depth and instance ids). Mask proposals are the
  ground-truth instance masks plus a coarse "table with everything on it" mask so that
  proposals overlap; features come from :class:`ColorNameEncoder`, which knows only colour
  words, so the queries are colours ("pink" is absent).

Each query is scored against the ground truth: whether it was found, the distance of the
region's median from the true object centre, and the 3D IoU of the selected points with
the points that truly lie on the object.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.perception.pipeline import frame_features
from conceptfusion.perception.featurizer import ORACLE_ENCODERS, PerceptionSpec, make_featurizer
from conceptfusion.synthetic import Box, orbit_poses, render_boxes, tabletop_boxes
from harness.demo.scoring import DemoConfig, demo_summary, score_queries
from harness.demo.tabletop import run_tabletop_demo

__all__ = ["run_demo", "points_on_box"]


def points_on_box(points_n3: np.ndarray, box: Box, *, tol: float = 0.01) -> np.ndarray:
    """Points within ``tol`` metres of the box's volume, (N,) bool."""
    return np.all((points_n3 >= box.lo - tol) & (points_n3 <= box.hi + tol), axis=1)


def _proposals(instance_hw: np.ndarray, objects: list[int], table: int) -> np.ndarray:
    masks = [instance_hw == i for i in objects + [table] if np.any(instance_hw == i)]
    group = np.isin(instance_hw, objects + [table])
    if group.any():
        masks.append(group)
    return np.stack(masks) if masks else np.zeros((0,) + instance_hw.shape, bool)


def run_demo(config: DemoConfig = DemoConfig(), out_dir: Path | None = None) -> dict:
    """Build the map, run the queries, optionally save map + PLY files; returns a summary.

    Raises:
        ValueError: unknown encoder spec (with the nearest names).
    """
    spec = PerceptionSpec.parse(config.encoder, proposer=config.proposer)
    if spec.encoder_name in ORACLE_ENCODERS:
        raise ValueError(f"encoder {spec.encoder_name!r}: the demo shows perception; choose an encoder such as 'embedded' or 'color'")
    featurizer = make_featurizer(spec)
    if spec.encoder_name != "color":
        return {"encoder": config.encoder, **run_tabletop_demo(config, featurizer, out_dir)}
    encoder = featurizer.encoder
    boxes = tabletop_boxes()
    table = next(i for i, b in enumerate(boxes) if b.name == "table")
    objects = [i for i, b in enumerate(boxes) if b.name not in ("floor", "table")]
    K = intrinsics_from_fovy(config.fovy_deg, config.width, config.height)
    fmap = PointFusionMap(encoder.dim)
    t_features = t_fuse = 0.0
    for pose in orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, config.frames):
        frame = render_boxes(boxes, K, pose, config.height, config.width)
        t0 = time.perf_counter()
        feats = frame_features(frame.rgb, _proposals(frame.segmentation, objects, table), encoder)
        t1 = time.perf_counter()
        fmap.integrate(frame.rgb, frame.depth, K, pose, feats)
        t_fuse += time.perf_counter() - t1
        t_features += t1 - t0
    points = fmap.points
    truths = {}
    for text in config.queries:
        box = next((b for b in boxes if b.name.startswith(text + " ")), None)
        truths[text] = None if box is None else (box.name, box.center, points_on_box(points, box))
    outcomes = score_queries(fmap, encoder, truths, out_dir, config)
    return {"encoder": config.encoder, **demo_summary("boxes", fmap, config.frames, t_features, t_fuse, outcomes)}
