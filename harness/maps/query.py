"""The ``query`` map suite (paper Tables I-III): text, image and click queries over a fused
tabletop map, scored against simulator ground truth.

**Task**: scan a shipped tabletop scene (orbit), fuse a map with the run's encoder and the
``rgbd`` proposer (oracles: privileged ground-truth features), then query every visible object
by its name (text), by a crop of it seen from a viewpoint outside the scan (image; lower and
closer orbit, cropped by its ground-truth mask box) and by a click on its surface (the fused
concept vector of the map point nearest its box centre).

**Ground truth**: a map point belongs to the object whose box (grown 1 cm) contains it (the
smallest such box), else to the background.

**Scoring**: per query the 3D IoU of the selected points with the object's points, for two
selections: ``region`` (the best region of :func:`conceptfusion.map.query.locate`, relative
threshold 0.6 for text and image, 0.8 for clicks as in the paper) and ``thresh`` (every point
whose relative score passes that threshold). Per modality: mIoU, detection accuracy at IoU >
0.15 / 0.25 / 0.5, found rate. ``absent_fp_rate``: two names of objects from other shipped
tables of the same world are queried; a ``found=True`` is a false positive. Image queries need an image tower:
with an oracle (``oracle``, ``oracle-open``) their metrics are ``None``. Objects with no map point are skipped (counted).
"""

from __future__ import annotations

import functools
import io
import math
import time
import zlib
from pathlib import Path

import numpy as np

from agents.builtin import make_mapper
from conceptfusion.io_utils import atomic_write_bytes
from conceptfusion.perception.featurizer import is_oracle
from harness.maps.scan import SceneScan, fuse_frames, load_shipped_scene, point_labels, scan_tabletop, scene_kind, shipped_scene_ids
from sim_envs.mujoco.scan import render_views

__all__ = ["run_query_scene", "locate_vector", "iou", "select_points", "MODALITIES", "IOU_LEVELS", "HEATMAP_VERSION", "RIGHT_IOU"]

MODALITIES = ("text", "image", "click")
IOU_LEVELS = (0.15, 0.25, 0.5)
_REL = {"text": 0.6, "image": 0.6, "click": 0.8}


def iou(selected_n: np.ndarray, truth_n: np.ndarray) -> float:
    """Intersection over union of two boolean point selections (0 when both are empty).

    Shape:
        (N,), (N,) bool -> float.
    """
    a, b = np.asarray(selected_n, bool), np.asarray(truth_n, bool)
    if a.shape != b.shape:
        raise ValueError(f"iou: expected two selections of the same length, got {a.shape} and {b.shape}")
    union = int((a | b).sum())
    return float((a & b).sum()) / union if union else 0.0


def locate_vector(mapper, query_d: np.ndarray, *, relative_threshold: float = 0.6):
    """:func:`conceptfusion.map.query.locate` with the mapper's settings, for any query vector
    (image embedding, click vector); the encoder's text score floor is not applied."""
    from conceptfusion.map.query import locate

    c = mapper.config
    return locate(
        mapper.map, np.asarray(query_d, np.float32), mapper.negatives(), relative_threshold=relative_threshold,
        relevancy_threshold=c.relevancy_threshold, voxel_size=c.voxel_size, min_points=c.min_points,
    )


def select_points(res, n: int, rel_th: float) -> tuple[np.ndarray, np.ndarray]:
    """The two point selections a query is scored by: ``region`` (the best region of a found
    answer, else nothing) and ``thresh`` (every point whose relative score reaches ``rel_th``).

    Shape:
        ``res`` over a map of ``n`` points -> (n,) bool, (n,) bool.
    """
    region = np.zeros(n, bool)
    if res.found:
        region[res.regions[0].indices_n] = True
    with np.errstate(invalid="ignore"):
        thresh = np.nan_to_num(res.relative_n, nan=-1.0) >= rel_th
    return region, thresh


def _novel_views(scan: SceneScan, width: int, height: int, n: int = 8) -> list:
    """Views off the scan's orbit: lower and closer, at angles between the scan's."""
    t = scan.scene.table
    cx, cy, _ = t.center
    target = (cx, cy, t.top_z)
    poses = []
    for k in range(n):
        a = 2 * math.pi * (k + 0.5) / n - math.pi / 2
        poses.append(((cx + 0.8 * math.cos(a), cy + 0.8 * math.sin(a), t.top_z + 0.45), target))
    return render_views(scan.sim, poses, width, height, geom_labels=scan.geom_labels)


def _image_query(encoder, views, label: int) -> np.ndarray | None:
    from conceptfusion.perception.features import mask_bboxes

    areas = [int((v.segmentation == label).sum()) for v in views]
    k = int(np.argmax(areas))
    if areas[k] < 20:
        return None
    mask = views[k].segmentation == label
    r0, c0, r1, c1 = mask_bboxes(mask[None])[0]
    h, w = mask.shape
    crop = views[k].rgb[max(r0 - 2, 0): min(r1 + 2, h), max(c0 - 2, 0): min(c1 + 2, w)]
    return np.asarray(encoder.encode_image([crop])[0], np.float32)


@functools.lru_cache(maxsize=None)
def _names_of_kind(kind: str) -> frozenset[str]:
    return frozenset(o.name for sid in shipped_scene_ids(kind) for o in load_shipped_scene(sid).objects)


def _absent_names(scene, seed: int, k: int = 2) -> list[str]:
    """``k`` names of objects on other shipped tables of the scene's world (v1 or v2), none on this one."""
    present = {o.name for o in scene.objects}
    try:
        kind = scene_kind(scene.id)
    except ValueError:
        kind = "tabletop"
    pool = sorted(_names_of_kind(kind) - present)
    rng = np.random.default_rng([int(seed), zlib.crc32(scene.id.encode())])
    return [str(x) for x in rng.choice(pool, size=min(k, len(pool)), replace=False)]


def _summary(ious: list[float | None], found: list[bool]) -> dict:
    vals = [v for v in ious if v is not None]
    if not vals:
        return {"miou": None, **{f"acc{int(t * 100)}": None for t in IOU_LEVELS}, "found_rate": None}
    arr = np.asarray(vals)
    out = {"miou": float(arr.mean())}
    out.update({f"acc{int(t * 100)}": float((arr > t).mean()) for t in IOU_LEVELS})
    out["found_rate"] = float(np.mean(found)) if found else None
    return out


HEATMAP_VERSION = 2
"""Version of the heatmap file :func:`run_query_scene` writes (1: ``points``, ``values``, ``query``
only; 2 adds the ground truth, the answer and the verdict)."""
RIGHT_IOU = 0.25
"""A query is answered right when its region's IoU with the object passes this (``text_acc25``)."""


def _scene_box(scan: SceneScan) -> np.ndarray:
    """The box around the table top and every object, (2, 3) lower and upper corners: what a
    top-down heatmap is cropped to (the floor around the table is left out)."""
    boxes = [np.asarray(scan.object_boxes, np.float64).reshape(-1, 2, 3)]
    t = scan.scene.table
    if t is not None:
        c, h = np.asarray(t.center, np.float64), np.asarray(t.size, np.float64) / 2
        boxes.append(np.stack([c - h, c + h])[None])
    allb = np.concatenate(boxes)
    return np.stack([allb[:, 0].min(axis=0), allb[:, 1].max(axis=0)])


def _save_heatmap(path, pts, res, obj, gt_box, scene_box, scored: dict) -> None:
    """Write a text query's heatmap file atomically (format :data:`HEATMAP_VERSION`): ``points``
    (N, 3) and ``values`` (N,) relevancy (0 where a point has no concept vector), ``query`` (the
    text), ``object`` (its id), ``gt_box`` (2, 3) the object's box, ``scene_box`` (2, 3) the table
    and objects, ``answer_indices`` (K,) the points of the found region (empty when not found),
    ``found``, ``iou``, ``iou_thresh``, ``right_iou`` and ``version``."""
    answer = res.regions[0].indices_n if res.found and res.regions else np.zeros(0, np.int64)
    buf = io.BytesIO()
    np.savez_compressed(
        buf, points=pts.astype(np.float32), values=np.nan_to_num(res.relevancy_n, nan=0.0).astype(np.float32),
        query=str(obj.name), object=str(obj.id), gt_box=np.asarray(gt_box, np.float32),
        scene_box=np.asarray(scene_box, np.float32), answer_indices=np.asarray(answer, np.int32),
        found=bool(scored["found"]), iou=float(scored["iou"]), iou_thresh=float(scored["iou_thresh"]),
        right_iou=float(RIGHT_IOU), version=int(HEATMAP_VERSION))
    atomic_write_bytes(path, buf.getvalue())


def run_query_scene(
    scene_id: str, encoder: str, *, frames: int = 12, width: int = 160, height: int = 120, seed: int = 0,
    heatmap_path: str | Path | None = None,
) -> tuple[dict, dict, dict]:
    """Run the query suite on one scene; returns ``(metrics, extras, timings)``.

    ``metrics``: ``{modality}_miou``, ``{modality}_acc15|25|50``, ``{modality}_found_rate``,
    ``{modality}_miou_thresh``, ``absent_fp_rate``, ``n_objects``, ``n_skipped``,
    ``map_points``. ``extras["queries"]``: one entry per object and modality. With
    ``heatmap_path``, the first scored object's text query is saved there as an .npz (see
    :func:`_save_heatmap`: relevancy per point, the query, its ground-truth box and its answer).
    """
    t0 = time.perf_counter()
    scan = scan_tabletop(scene_id, "query", frames=frames, width=width, height=height)
    t_scan = time.perf_counter() - t0
    mapper = fuse_frames(make_mapper(encoder, "rgbd"), scan)
    t_fuse = time.perf_counter() - t0 - t_scan
    fmap = mapper.map
    pts = fmap.points
    gt = point_labels(pts, scan.object_boxes)
    views = None if is_oracle(encoder) else _novel_views(scan, width, height)
    from conceptfusion.map.query import click_query_vector

    ious = {m: [] for m in MODALITIES}
    ious_t = {m: [] for m in MODALITIES}
    found = {m: [] for m in MODALITIES}
    queries, skipped = [], 0
    for i, obj in enumerate(scan.scene.objects):
        truth = np.isin(gt, [j for j, o in enumerate(scan.scene.objects) if o.name == obj.name])
        if not truth.any():
            skipped += 1
            continue
        entry = {"object": obj.id, "name": obj.name, "gt_points": int(truth.sum())}
        vectors = {"text": None, "image": None, "click": None}
        res_text = mapper.locate(obj.name)
        if views is not None:
            vectors["image"] = _image_query(mapper.encoder, views, i)
        centre = scan.object_boxes[i].mean(axis=0)
        own = np.flatnonzero((gt == i) & fmap.has_feature)
        if own.size:
            click = pts[own[np.argmin(np.sum((pts[own] - centre) ** 2, axis=1))]]
            vectors["click"] = click_query_vector(fmap, click)
        for m in MODALITIES:
            if m == "text":
                res = res_text
            elif vectors[m] is None:
                entry[m] = None
                continue
            else:
                res = locate_vector(mapper, vectors[m], relative_threshold=_REL[m])
            region, thresh = select_points(res, len(pts), _REL[m])
            v, vt = iou(region, truth), iou(thresh, truth)
            ious[m].append(v)
            ious_t[m].append(vt)
            found[m].append(bool(res.found))
            entry[m] = {"iou": round(v, 4), "iou_thresh": round(vt, 4), "found": bool(res.found)}
        if heatmap_path is not None and not queries:
            _save_heatmap(heatmap_path, pts, res_text, obj, scan.object_boxes[i], _scene_box(scan), entry["text"])
        queries.append(entry)
    absent = []
    for name in _absent_names(scan.scene, seed):
        absent.append({"name": name, "found": bool(mapper.locate(name).found)})
    metrics: dict = {}
    for m in MODALITIES:
        for k, v in _summary(ious[m], found[m]).items():
            metrics[f"{m}_{k}"] = v
        metrics[f"{m}_miou_thresh"] = float(np.mean(ious_t[m])) if ious_t[m] else None
    metrics.update({
        "absent_fp_rate": float(np.mean([a["found"] for a in absent])) if absent else None,
        "n_objects": len(queries), "n_skipped": skipped, "map_points": int(len(pts)),
    })
    extras = {"queries": queries, "absent": absent, "frames": frames, "image_size": [width, height],
              "privileged": bool(mapper.privileged)}
    timings = {"scan_s": t_scan, "fuse_s": t_fuse, "query_s": time.perf_counter() - t0 - t_scan - t_fuse}
    return metrics, extras, timings
