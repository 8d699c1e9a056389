"""The ``ablation`` map suite (the paper's ablation of pixel-aligned features).

**Task**: scan a shipped tabletop scene (orbit), fuse one map per variant of the pixel
features: ``global`` (every masked pixel gets the frame's global embedding), ``local`` (each
mask's crop embedding only), ``no-uniqueness`` (eq. 5 without the uniqueness term) and
``full`` (eqs. 3-6).

**Ground truth**: each map point is an object (box membership, see
:func:`harness.maps.scan.point_labels`), else ``"table"`` (within 2 cm of the table top, inside
its footprint), else ``"floor"``.

**Scoring**: map-point semantic segmentation of the points within 0.3 m (horizontally) of
the table's footprint (the far floor would otherwise outweigh everything else). A point's class is the argmax cosine of its
concept vector over the texts {object names} + {"table", "floor"}; a point without a concept
vector counts as wrong. ``macc``: mean over the ground-truth classes of per-class accuracy;
``fmiou``: frequency-weighted IoU; ``coverage``: share of points with a concept vector.
"""

from __future__ import annotations

import time

import numpy as np

from agents.builtin import make_mapper
from conceptfusion.perception.featurizer import PerceptionSpec
from harness.maps.scan import fuse_frames, point_labels, scan_tabletop

__all__ = ["VARIANTS", "segmentation_scores", "run_ablation_scene", "ground_truth_classes"]

VARIANTS: dict[str, dict] = {
    "global": {"mode": "global"},
    "local": {"mode": "local"},
    "no-uniqueness": {"mode": "full", "uniqueness": False},
    "full": {"mode": "full"},
}
"""Variant name -> the feature mode of its
:class:`~conceptfusion.perception.featurizer.PerceptionSpec` (``mode``, ``uniqueness``)."""


def segmentation_scores(pred_n: np.ndarray, true_n: np.ndarray, num_classes: int) -> dict:
    """Mean class accuracy and frequency-weighted IoU of a point labelling.

    ``pred_n`` may hold -1 (no prediction: wrong for every class). Classes absent from
    ``true_n`` do not enter either mean.

    Shape:
        (N,), (N,) int -> {"macc", "fmiou", "pixel_acc"} floats.
    """
    pred, true = np.asarray(pred_n, np.int64), np.asarray(true_n, np.int64)
    if pred.shape != true.shape or pred.ndim != 1:
        raise ValueError(f"segmentation_scores: expected two (N,) label arrays, got {pred.shape} and {true.shape}")
    if true.size == 0:
        raise ValueError("segmentation_scores: expected at least one labelled point, got none")
    if true.min() < 0 or true.max() >= num_classes:
        raise ValueError(f"segmentation_scores: expected true labels in [0, {num_classes}), got [{true.min()}, {true.max()}]")
    accs, fw = [], 0.0
    for c in np.unique(true):
        t, p = true == c, pred == c
        accs.append(float((t & p).sum() / t.sum()))
        fw += float(t.mean()) * float((t & p).sum() / (t | p).sum())
    return {"macc": float(np.mean(accs)), "fmiou": fw, "pixel_acc": float((pred == true).mean())}


def ground_truth_classes(points_n3: np.ndarray, scan) -> tuple[np.ndarray, list[str]]:
    """Class of every map point and the class names: objects (scene order), ``"table"``, ``"floor"``.

    Shape:
        ``points_n3`` (N, 3) -> (N,) int64 in ``[0, n + 2)``, list of n + 2 names.
    """
    scene = scan.scene
    n = len(scene.objects)
    obj = point_labels(points_n3, scan.object_boxes)
    t = scene.table
    lo = np.asarray(t.center[:2]) - np.asarray(t.size[:2]) / 2
    hi = np.asarray(t.center[:2]) + np.asarray(t.size[:2]) / 2
    pts = np.asarray(points_n3)
    on_table = (np.abs(pts[:, 2] - t.top_z) <= 0.02) & np.all((pts[:, :2] >= lo) & (pts[:, :2] <= hi), axis=1)
    cls = np.where(obj >= 0, obj, np.where(on_table, n, n + 1))
    return cls, [o.name for o in scene.objects] + ["table", "floor"]


def _classify(fmap, text_vectors_kd: np.ndarray) -> np.ndarray:
    scores = np.stack([fmap.scores(v) for v in text_vectors_kd])  # (K, N), NaN without feature
    pred = np.argmax(np.nan_to_num(scores, nan=-np.inf), axis=0)
    return np.where(fmap.has_feature, pred, -1)


def run_ablation_scene(
    scene_id: str, variant: str, encoder: str, *, proposer: str = "rgbd", frames: int = 12, width: int = 160, height: int = 120,
) -> tuple[dict, dict, dict]:
    """One scene, one variant; returns ``(metrics, extras, timings)``.

    ``encoder`` is an encoder spec (``"embedded"``, ``"color"``, ...); the variant's featurizer
    is built by :func:`agents.builtin.make_mapper` (the encoder is loaded once per process).
    """
    if variant not in VARIANTS:
        raise ValueError(f"ablation variant: expected one of {list(VARIANTS)}, got {variant!r}")
    t0 = time.perf_counter()
    scan = scan_tabletop(scene_id, "ablation", frames=frames, width=width, height=height)
    t_scan = time.perf_counter() - t0
    mapper = fuse_frames(make_mapper(PerceptionSpec.parse(encoder, proposer=proposer, **VARIANTS[variant])), scan)
    fmap = mapper.map
    t_fuse = time.perf_counter() - t0 - t_scan
    t = scan.scene.table
    near = np.all(np.abs(fmap.points[:, :2] - np.asarray(t.center[:2])) <= np.asarray(t.size[:2]) / 2 + 0.3, axis=1)
    true, names = ground_truth_classes(fmap.points[near], scan)
    pred = _classify(fmap, np.asarray(mapper.featurizer.encode_text(names), np.float32))[near]
    metrics = segmentation_scores(pred, true, len(names))
    metrics.update({"coverage": float(fmap.has_feature[near].mean()), "map_points": int(near.sum()), "n_classes": int(len(np.unique(true)))})
    per_class = {names[c]: round(float((pred[true == c] == c).mean()), 4) for c in np.unique(true)}
    extras = {"per_class_acc": per_class, "proposer": proposer, "frames": frames, "image_size": [width, height],
              "privileged": bool(mapper.privileged)}
    timings = {"scan_s": t_scan, "fuse_s": t_fuse, "score_s": time.perf_counter() - t0 - t_scan - t_fuse}
    return metrics, extras, timings
