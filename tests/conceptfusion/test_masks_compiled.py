"""The compiled paths of the RGB-D proposer give, bit for bit, what the array formulation gives.

The references below are the proposer's array formulation (numpy and scipy, as described in
:mod:`conceptfusion.perception.masks.rgbd` and :mod:`conceptfusion.perception.masks.regions`);
the compiled kernels must reproduce every value, so the masks do not depend on which one runs.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from conceptfusion.cameras import backproject, intrinsics_from_fovy
from conceptfusion.perception.masks import pixel_graph, regions
from conceptfusion.perception.masks.base import check_frame
from conceptfusion.perception.masks.rgbd import RGBDProposer
from conceptfusion.perception.masks.rgbd_config import RGBDProposerConfig
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes

H, W = 96, 128
K = intrinsics_from_fovy(60.0, W, H)


def _frames():
    """Box-scene frames: exact, with sensor-like noise and holes, and with a textured image."""
    rng = np.random.default_rng(7)
    out = []
    for k, pose in enumerate(orbit_poses((0.0, 0.0, 0.45), 1.2, 0.7, 3, start_deg=20.0)):
        f = render_boxes(tabletop_boxes(), K, pose, H, W)
        depth = f.depth.astype(np.float32)
        rgb = f.rgb
        if k >= 1:
            depth = depth + rng.normal(0.0, 0.004, depth.shape).astype(np.float32)
            depth[rng.random(depth.shape) < 0.03] = np.nan
        if k == 2:
            rgb = np.clip(rgb.astype(int) + rng.integers(-20, 21, rgb.shape), 0, 255).astype(np.uint8)
        out.append((rgb, depth))
    return out


FRAMES = _frames()
CONFIGS = [RGBDProposerConfig(), RGBDProposerConfig(lightness_weight=0.3, color_scale=4.0, depth_tol=0.02,
                                                    normal_tol_deg=33.0, convex_weight=0.4, max_term=3.5)]


# -- the array formulation ---------------------------------------------------------------------

def _ref_normals(vertex_hw3):
    v = vertex_hw3.astype(np.float32)
    tangents = []
    for axis in (1, 0):
        d = np.diff(v, axis=axis)
        pad = np.full_like(np.take(d, [0], axis=axis), np.nan)
        fwd = np.concatenate([d, pad], axis=axis)
        bwd = np.concatenate([pad, d], axis=axis)
        with np.errstate(invalid="ignore"):
            use_bwd = np.isnan(fwd[..., 2]) | (np.abs(bwd[..., 2]) < np.abs(fwd[..., 2]))
        tangents.append(np.where(use_bwd[..., None], bwd, fwd))
    n = np.cross(tangents[0], tangents[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        flip = np.sum(n * v, axis=-1, keepdims=True) > 0
    return np.where(flip, -n, n).astype(np.float32)


def _ref_depth_jump(inv_hw, axis):
    x = inv_hw if axis == 1 else inv_hw.T
    s = np.diff(x, axis=1)
    pad = np.full((x.shape[0], 1), np.nan, x.dtype)
    prev = np.concatenate([pad, s[:, :-1]], axis=1)
    nxt = np.concatenate([s[:, 1:], pad], axis=1)
    with np.errstate(invalid="ignore"):
        dev = np.fmin(np.abs(s - prev), np.abs(s - nxt))
        dev = np.where(np.isnan(prev) & np.isnan(nxt), np.abs(s), dev)
        rel = dev / (0.5 * (x[:, :-1] + x[:, 1:]))
    return rel if axis == 1 else rel.T


def _ref_edges(lab, inv, vertex, normals, valid, cfg):
    h, w = inv.shape
    lab_weight = np.array([cfg.lightness_weight, 1.0, 1.0], np.float32)
    cos_tol = math.cos(math.radians(cfg.normal_tol_deg))
    idx = np.arange(h * w, dtype=np.int64).reshape(h, w)
    srcs, dsts, weights = [], [], []
    for axis in (1, 0):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        color = np.linalg.norm((lab[a] - lab[b]) * lab_weight, axis=-1) / cfg.color_scale
        depth_cost = _ref_depth_jump(inv, axis) / cfg.depth_tol
        with np.errstate(invalid="ignore"):
            dot = np.sum(normals[a] * normals[b], axis=-1)
            convex = np.sum((normals[a] - normals[b]) * (vertex[a] - vertex[b]), axis=-1) > 0
        normal_cost = np.nan_to_num((1.0 - dot) / (1.0 - cos_tol), nan=0.0)
        normal_cost = np.where(convex, cfg.convex_weight * normal_cost, normal_cost)
        geo = np.minimum(np.nan_to_num(depth_cost, nan=0.0), cfg.max_term) + np.minimum(normal_cost, cfg.max_term)
        both = valid[a] & valid[b]
        one = valid[a] ^ valid[b]
        geo = np.where(both, geo, np.where(one, 2.0 * cfg.max_term, 0.0))
        weights.append((np.minimum(color, cfg.max_term) + geo).astype(np.float32).ravel())
        srcs.append(idx[a].ravel())
        dsts.append(idx[b].ravel())
    return np.concatenate(srcs), np.concatenate(dsts), np.concatenate(weights)


def _ref_merge_levels(fine, count, src, dst, weight, thresholds):
    cross = fine[src] != fine[dst]
    bs, bd, bw = src[cross], dst[cross], weight[cross].astype(np.float64)
    levels, counts = [fine], [count]
    lab, m = fine, count
    for t in thresholds:
        while True:
            a, b = lab[bs], lab[bd]
            keep = a != b
            lo, hi = np.minimum(a, b)[keep], np.maximum(a, b)[keep]
            if len(lo) == 0:
                break
            pairs, inv = np.unique(lo * m + hi, return_inverse=True)
            mean = np.bincount(inv, weights=bw[keep]) / np.bincount(inv)
            join = mean <= t
            if not join.any():
                break
            graph = coo_matrix((np.ones(int(join.sum())), (pairs[join] // m, pairs[join] % m)), shape=(m, m))
            m, comp = connected_components(graph, directed=False)
            lab = comp.astype(np.int64)[lab]
        levels.append(lab)
        counts.append(m)
    return np.stack(levels), np.asarray(counts, np.int64)


def _ref_duplicates(lab_a, m_a, area_a, kept_a, lab_b, m_b, area_b, iou_th):
    codes = lab_a.astype(np.int64) * m_b + lab_b
    pairs, inter = np.unique(codes, return_counts=True)
    ia, ib = pairs // m_b, pairs % m_b
    iou = inter / (area_a[ia] + area_b[ib] - inter)
    hit = kept_a[ia] & (iou >= iou_th)
    dup = np.zeros(m_b, bool)
    dup[ib[hit]] = True
    return dup


def _graph_inputs(rgb, depth, cfg):
    rgb, depth, k = check_frame(rgb, depth, K)
    valid = np.isfinite(depth)
    vertex = backproject(depth, k)
    img = cv2.GaussianBlur(rgb.astype(np.float32) / 255.0, (0, 0), cfg.blur_sigma)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    inv = np.where(valid, 1.0 / np.where(valid, depth, 1.0), np.nan).astype(np.float32)
    return lab, inv, vertex, valid


def _same_bits(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


# -- the tests -------------------------------------------------------------------------------

@pytest.mark.parametrize("k", range(len(FRAMES)))
def test_normals_equal_the_array_formulation_bit_for_bit(k):
    rgb, depth = FRAMES[k]
    _, _, vertex, _ = _graph_inputs(rgb, depth, CONFIGS[0])
    ref = _ref_normals(vertex)
    got = pixel_graph.edge_aware_normals(vertex)
    assert np.isfinite(ref).any() and np.isnan(ref).any()  # both paths of the kernel are exercised
    assert _same_bits(got, ref)


@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("k", range(len(FRAMES)))
def test_edge_weights_equal_the_array_formulation_bit_for_bit(k, cfg):
    rgb, depth = FRAMES[k]
    lab, inv, vertex, valid = _graph_inputs(rgb, depth, cfg)
    normals = _ref_normals(vertex)
    rs, rd, rw = _ref_edges(lab, inv, vertex, normals, valid, cfg)
    gs, gd, gw = pixel_graph.edge_weights(lab, inv, vertex, normals, valid, cfg)
    assert len(rw) == H * (W - 1) + (H - 1) * W
    assert np.array_equal(gs, rs) and np.array_equal(gd, rd)
    assert _same_bits(gw, rw)
    if k == 0:
        assert (rw < 0).any()  # exact planes give tiny negative normal costs: stable_order must handle them


def test_stable_order_is_the_stable_argsort():
    rng = np.random.default_rng(3)
    for n in (0, 1, 5, 1000, 40000):
        w = ((rng.random(n) - 0.2) * rng.uniform(0.1, 20.0)).astype(np.float32)
        w[::3] = 12.0
        w[::7] = 0.0
        w[::11] = -0.0
        w[::13] = -1e-6
        w[::17] = np.inf
        w[::19] = -np.inf
        assert np.array_equal(pixel_graph.stable_order(w), np.argsort(w, kind="stable"))
    w = np.array([1.0, np.nan, 0.5, np.nan, 0.5], np.float32)
    assert np.array_equal(pixel_graph.stable_order(w), np.argsort(w, kind="stable"))


@pytest.mark.parametrize("k", range(len(FRAMES)))
def test_merge_levels_and_duplicates_equal_the_scipy_formulation(k):
    cfg = CONFIGS[0]
    rgb, depth = FRAMES[k]
    lab, inv, vertex, valid = _graph_inputs(rgb, depth, cfg)
    src, dst, weight = pixel_graph.edge_weights(lab, inv, vertex, _ref_normals(vertex), valid, cfg)
    order = np.argsort(weight, kind="stable")
    n = H * W
    fine, count = regions.felzenszwalb(src[order], dst[order], weight[order], n, 20.0, 8)
    thresholds = (1.0, 2.0, 4.0, 7.0)
    got_labels, got_counts = regions.merge_levels(fine, count, src, dst, weight, thresholds)
    ref_labels, ref_counts = _ref_merge_levels(fine, count, src, dst, weight, thresholds)
    assert np.array_equal(got_counts, ref_counts) and np.array_equal(got_labels, ref_labels)
    assert ref_counts[0] > ref_counts[-1]  # the levels do merge
    areas = [np.bincount(lab, minlength=m).astype(np.float64) for lab, m in zip(ref_labels, ref_counts)]
    for a, b in ((0, 1), (0, 3), (1, 2)):
        kept = np.ones(int(ref_counts[a]), bool)
        kept[::2] = False
        for th in (0.5, 0.9):
            want = _ref_duplicates(ref_labels[a], int(ref_counts[a]), areas[a], kept, ref_labels[b], int(ref_counts[b]), areas[b], th)
            got = regions._duplicates(ref_labels[a], int(ref_counts[a]), areas[a], kept, ref_labels[b], int(ref_counts[b]),
                                      areas[b], th)
            assert np.array_equal(got, want)


def test_pixels_on_a_plane_equal_the_matrix_product_and_fall_back_at_the_tolerance():
    rng = np.random.default_rng(5)
    p = rng.normal(0.0, 1.5, (5000, 3))
    valid = rng.random(5000) > 0.1
    p[~valid] = 0.0
    mean = np.array([0.1, -0.2, 1.3])
    normal = np.array([0.2, -0.3, 0.9])
    normal /= np.linalg.norm(normal)
    dist = np.abs((p - mean) @ normal)
    for tol in (0.01, 0.3, float(np.median(dist))):
        want = valid & (dist <= tol)
        assert np.array_equal(regions._pixels_on_plane(p, valid, mean, normal, tol), want)
    # A point exactly at the tolerance takes the matrix product's answer.
    tol = float(dist[np.flatnonzero(valid)[0]])
    _, ambiguous = regions._plane_pixels_kernel(p, valid, mean, normal, tol)
    assert ambiguous
    assert np.array_equal(regions._pixels_on_plane(p, valid, mean, normal, tol), valid & (dist <= tol))


def test_repeated_frame_gives_the_same_masks_from_the_cache():
    proposer = RGBDProposer()
    rgb, depth = FRAMES[0]
    first, level = proposer.segment(rgb, depth, K)
    first[...] = False  # callers own what they get
    again, level_again = proposer.segment(rgb.copy(), depth.copy(), K)
    fresh, fresh_level = RGBDProposer().segment(rgb, depth, K)
    assert len(fresh) > 0
    assert np.array_equal(again, fresh) and np.array_equal(level_again, fresh_level)
    other = depth.copy()
    other[np.isfinite(other)] += 0.5
    assert len(proposer._recent) == 1
    proposer.segment(rgb, other, K)
    assert len(proposer._recent) == 2
