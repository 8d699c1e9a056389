"""Feature inputs of the map: dense arrays, label image + table, per-pixel quantisation,
compact storage sizes, and threaded scoring."""

import logging

import numpy as np
import pytest

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import DtypeError, ShapeError
from conceptfusion.map import _association, dense, feature_store
from conceptfusion.map import fusion as fusion_module
from conceptfusion.map._rowhash import hash_weights
from conceptfusion.map._threads import balanced_bounds, map_bounds, run_ranges
from conceptfusion.map.dense import palette_from_dense
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.quantize import quantize_features
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.synthetic import Box, orbit_poses, render_boxes

H, W = 48, 64
K = intrinsics_from_fovy(60.0, W, H)
BOXES = [
    Box("floor", (0.0, 0.0, -0.05), (3.0, 3.0, 0.1), (150, 150, 150)),
    Box("cube", (0.1, 0.0, 0.1), (0.2, 0.2, 0.2), (200, 0, 0)),
    Box("slab", (-0.3, 0.2, 0.05), (0.3, 0.2, 0.1), (0, 0, 200)),
]


def _frames(n=4, dim=6, seed=0):
    """Rendered frames with palette features: (object, image quadrant) parts, fresh noise per frame."""
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(len(BOXES), dim))
    out = []
    for pose in orbit_poses((0.0, 0.0, 0.0), 1.2, 0.9, n, sweep_deg=90.0):
        f = render_boxes(BOXES, K, pose, H, W)
        quad = (np.arange(H)[:, None] >= H // 2) * 2 + (np.arange(W)[None, :] >= W // 2)
        key = np.where(f.segmentation >= 0, f.segmentation * 4 + quad, -1)
        uniq, inv = np.unique(key, return_inverse=True)
        pal = (base[np.maximum(uniq, 0) // 4] + 0.3 * rng.normal(size=(len(uniq), dim))).astype(np.float32)
        index = np.where(uniq[inv.reshape(H, W)] >= 0, inv.reshape(H, W), -1).astype(np.int32)
        out.append((f.rgb, f.depth, pose, PixelFeatures(pal, index)))
    return out


def _first_appearance(pf: PixelFeatures) -> PixelFeatures:
    """The same features with palette rows ordered by their first pixel (raster order)."""
    idx = pf.index_hw.ravel()
    used = idx[idx >= 0]
    uniq, first = np.unique(used, return_index=True)
    order = uniq[np.argsort(first)]
    remap = np.full(len(pf.palette_pd) + 1, -1, np.int32)
    remap[order] = np.arange(len(order))
    return PixelFeatures(pf.palette_pd[order], remap[pf.index_hw])


def _fuse(frames, convert, **kw):
    fmap = PointFusionMap(frames[0][3].dim, **kw)
    for rgb, depth, pose, pf in frames:
        fmap.integrate(rgb, depth, K, pose, convert(pf))
    return fmap


def _assert_same_state(a, b):
    ha, aa = a.state_dict()
    hb, ab = b.state_dict()
    assert ha == hb
    for name in aa:
        assert aa[name].dtype == ab[name].dtype and np.array_equal(aa[name], ab[name]), name


def test_dense_input_gives_the_palette_map_bit_for_bit():
    frames = _frames()
    from_palette = _fuse(frames, _first_appearance, slots=2)  # 2 slots: the full-slot rule runs too
    from_dense = _fuse(frames, lambda pf: pf.dense(), slots=2)
    _assert_same_state(from_palette, from_dense)
    # any palette order gives the same concept vectors (bank ids aside)
    shuffled = _fuse(frames, lambda pf: pf, slots=2)
    q = np.random.default_rng(1).normal(size=6)
    assert np.allclose(shuffled.features(), from_dense.features(), atol=1e-6)
    assert np.allclose(shuffled.scores(q), from_dense.scores(q), atol=1e-6, equal_nan=True)
    assert np.array_equal(shuffled.points, from_dense.points)


def test_label_image_and_table_equal_pixel_features():
    frames = _frames(n=3)
    a = _fuse(frames, lambda pf: pf)
    b = _fuse(frames, lambda pf: (pf.index_hw, pf.palette_pd))
    _assert_same_state(a, b)


def test_label_table_pairs_are_checked():
    rgb, depth, pose, pf = _frames(n=1)[0]
    fmap = PointFusionMap(6)
    with pytest.raises(ShapeError, match=r"feats_hwd table: expected shape \(\*, 6\)"):
        fmap.integrate(rgb, depth, K, pose, (pf.index_hw, pf.palette_pd[:, :5]))
    with pytest.raises(ShapeError, match=r"feats_hwd labels: expected shape \(48, 64\)"):
        fmap.integrate(rgb, depth, K, pose, (pf.index_hw[:10], pf.palette_pd))
    with pytest.raises(DtypeError, match="feats_hwd labels: expected dtype kind"):
        fmap.integrate(rgb, depth, K, pose, (pf.index_hw.astype(np.float32), pf.palette_pd))
    with pytest.raises(ShapeError, match=r"index_hw: expected values in \[-1, 1\]"):
        fmap.integrate(rgb, depth, K, pose, (pf.index_hw, pf.palette_pd[:2]))
    with pytest.raises(DtypeError, match="a \\(labels \\(H, W\\), table \\(P, d\\)\\) pair, got list"):
        fmap.integrate(rgb, depth, K, pose, [pf.index_hw, pf.palette_pd])
    assert len(fmap) == 0


def test_palette_from_dense_worked_example():
    a, b = [1.0, 2.0], [3.0, -1.0]
    z, nz = [0.0, 0.0], [-0.0, 0.0]
    f = np.array([[a, a, b], [z, b, nz], [a, [1.0, 2.0000002], b]], np.float32)
    pf = palette_from_dense(f)
    # entries in order of first pixel: a, b, then a's neighbour in float32 (a distinct row)
    assert np.array_equal(pf.palette_pd, np.array([a, b, [1.0, 2.0000002]], np.float32))
    assert np.array_equal(pf.index_hw, [[0, 0, 1], [-1, 1, -1], [0, 2, 1]])
    assert pf.index_hw.dtype == np.int32
    assert palette_from_dense(np.zeros((2, 3, 4), np.float32)).palette_pd.shape == (0, 4)
    with pytest.raises(ValueError, match="expected finite features"):
        palette_from_dense(np.array([[a, [np.nan, 1.0]]], np.float32))
    with pytest.raises(ValueError, match="expected finite features"):
        palette_from_dense(np.array([[[np.inf, 1.0]]], np.float64))
    with pytest.raises(ShapeError, match=r"feats_hwd: expected shape \(\*, \*, \*\)"):
        palette_from_dense(np.zeros((4, 4), np.float32))


def test_dense_grouping_is_exact_even_when_every_hash_collides():
    rng = np.random.default_rng(0)
    f = rng.integers(0, 3, size=(20, 30, 4)).astype(np.float32)  # many repeats, some zero rows
    bits = np.ascontiguousarray(f.reshape(-1, 4)).view(np.int32)
    first, index, finite = dense._group_rows(bits, hash_weights(4))
    first0, index0, finite0 = dense._group_rows(bits, np.zeros(4, np.uint64))  # one bucket for all
    assert finite and finite0
    assert np.array_equal(first, first0) and np.array_equal(index, index0)
    rows = f.reshape(-1, 4)
    nonzero = np.any(rows != 0, axis=1)
    assert np.array_equal(rows[first][index[nonzero]], rows[nonzero])  # every pixel keeps its row
    assert np.all(index[~nonzero] == -1)
    assert len(np.unique(rows[first], axis=0)) == len(first)  # entries are distinct


def test_per_pixel_features_make_one_entry_per_pixel_and_warn(caplog, monkeypatch):
    rng = np.random.default_rng(2)
    rgb, depth, pose, _ = _frames(n=1)[0]
    f = rng.normal(size=(H, W, 6)).astype(np.float32)
    pf = palette_from_dense(f)
    assert len(pf.palette_pd) == H * W
    assert np.array_equal(pf.index_hw.ravel(), np.arange(H * W))
    monkeypatch.setattr("conceptfusion.map.fusion._LARGE_PALETTE", 100)
    with caplog.at_level(logging.WARNING, logger="conceptfusion.map.fusion"):
        PointFusionMap(6).integrate(rgb, depth, K, pose, f)
    assert "3072 distinct features" in caplog.text and "quantize_features" in caplog.text


def test_quantisation_is_exact_for_few_directions_and_bounded_otherwise():
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(3, 8)).astype(np.float32)
    label = rng.integers(-1, 3, size=(H, W))
    f = np.where(label[..., None] >= 0, dirs[np.maximum(label, 0)] * rng.uniform(0.5, 2.0, (H, W, 1)), 0.0)
    pf = quantize_features(f.astype(np.float32), entries=16)
    assert len(pf.palette_pd) == 3  # three directions: three entries, whatever k is
    unit = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    got = pf.dense()
    has = label >= 0
    assert np.allclose(got[has], unit[label[has]], atol=1e-6)
    assert np.all(pf.index_hw[~has] == -1)
    # per-pixel noise: at most `entries` unit rows; pixels were assigned to the k-means centres
    # before each entry became the mean of its pixels, so nearly all sit on their best entry
    g = rng.normal(size=(H, W, 8)).astype(np.float32)
    pq = quantize_features(g, entries=5, seed=4)
    assert 1 <= len(pq.palette_pd) <= 5
    assert np.allclose(np.linalg.norm(pq.palette_pd, axis=1), 1.0, atol=1e-6)
    sims = g.reshape(-1, 8) @ pq.palette_pd.T
    chosen = sims[np.arange(H * W), pq.index_hw.ravel()]
    assert np.mean(chosen >= sims.max(axis=1) - 1e-4) > 0.9
    assert np.mean(chosen) > np.mean(sims)  # better than an arbitrary entry
    again = quantize_features(g, entries=5, seed=4)
    assert np.array_equal(again.palette_pd, pq.palette_pd) and np.array_equal(again.index_hw, pq.index_hw)
    with pytest.raises(ValueError, match="entries: expected an integer >= 1, got 0"):
        quantize_features(g, entries=0)
    with pytest.raises(ValueError, match="expected finite features"):
        quantize_features(np.full((2, 2, 3), np.nan, np.float32))


def test_compact_store_sizes():
    # geometry 10 float32 = 40 B; ids 8 x 4, weights 8 x 4, off-diagonal Gram 28 x 4, |S|^2 8
    assert feature_store.FeatureStore(512, 8).bytes_per_point() == 32 + 32 + 112 + 8
    frames = _frames(n=2)
    fmap = _fuse(frames, lambda pf: pf)
    bank = fmap._store.bank
    assert fmap.nbytes() == len(fmap) * (40 + 184) + fmap._store.nbytes(0)
    # the shared part: each bank row, its squared norm and hash, and the hash table
    assert fmap._store.nbytes(0) == len(bank) * (6 * 4 + 4 + 8) + fmap._store._table.nbytes
    # the saved Gram matrices keep their diagonal: the squared norms of the bank entries
    _, arrays = fmap.state_dict()
    ids = arrays["feat_point_ids"]
    diag = arrays["feat_point_gram"][:, [0, 8, 15, 21, 26, 30, 33, 35]]
    sq = np.einsum("pd,pd->p", bank, bank)
    assert np.array_equal(diag[ids >= 0], sq[ids[ids >= 0]])
    assert np.all(diag[ids < 0] == 0)


def test_threaded_scores_equal_one_pass(monkeypatch):
    frames = _frames(n=3)
    fmap = _fuse(frames, lambda pf: pf)
    q = np.random.default_rng(5).normal(size=6)
    whole = fmap.scores(q)
    monkeypatch.setattr(feature_store, "_SCORE_CHUNK", 97)
    monkeypatch.setattr("numba.config.NUMBA_NUM_THREADS", 3)
    assert np.array_equal(fmap.scores(q), whole, equal_nan=True)
    seen = []
    run_ranges(lambda a, b: seen.append((a, b)), 10, min_chunk=3)
    assert sorted(seen) == [(0, 3), (3, 6), (6, 10)]


def test_balanced_bounds_give_each_thread_its_share_of_the_work(monkeypatch):
    monkeypatch.setattr("numba.config.NUMBA_NUM_THREADS", 2)
    even = np.arange(0, 1001, 10, dtype=np.float64)  # cost 1 per item, sampled every 10 items
    assert balanced_bounds(1000, even, 10, min_chunk=100) == [0, 500, 1000]
    # the last fifth of the items does 4x the work of the rest together: the split moves into it
    per_sample = np.r_[np.ones(80), 16 * np.ones(20)]
    skewed = np.r_[0.0, np.cumsum(per_sample * 10)]
    b = balanced_bounds(1000, skewed, 10, min_chunk=100)
    assert b[0] == 0 and b[-1] == 1000 and len(b) == 3 and 800 < b[1] < 1000 and b[1] % 10 == 0
    cost_before = skewed[b[1] // 10]
    assert abs(cost_before - (skewed[-1] - cost_before)) <= 16 * 10
    # no work at all, or too few items to split: the plain split
    assert balanced_bounds(1000, np.zeros(101), 10, min_chunk=100) == [0, 500, 1000]
    assert balanced_bounds(150, np.arange(0, 151, 10.0), 10, min_chunk=100) == [0, 150]
    # all the work in the first sample: no empty range
    front = np.r_[0.0, np.full(100, 1000.0)]
    assert balanced_bounds(1000, front, 10, min_chunk=100) == [0, 10, 1000]
    seen = []
    assert map_bounds(lambda a, c: seen.append((a, c)) or (a, c), [0, 7, 9, 12]) == [(0, 7), (7, 9), (9, 12)]
    assert sorted(seen) == [(0, 7), (7, 9), (9, 12)]


def test_dense_grouping_split_over_threads_is_the_same(monkeypatch):
    rng = np.random.default_rng(6)
    f = rng.integers(0, 4, size=(30, 40, 3)).astype(np.float32)
    f[10:12] = 0.0  # a block of zero rows: one range may hold no entry at all
    whole = palette_from_dense(f)
    monkeypatch.setattr(dense, "_THREAD_ROWS", 100)
    monkeypatch.setattr("numba.config.NUMBA_NUM_THREADS", 7)
    split = palette_from_dense(f)
    assert np.array_equal(split.palette_pd, whole.palette_pd)
    assert np.array_equal(split.index_hw, whole.index_hw)


def test_association_split_over_threads_is_the_same(monkeypatch):
    frames = _frames(n=3)
    fmap = _fuse(frames[:2], lambda pf: pf)
    rgb, depth, pose, pf = frames[2]
    one = _fuse(frames[:2], lambda pf: pf)
    monkeypatch.setattr(_association, "_THREAD_CHUNK", 50)
    monkeypatch.setattr(_association, "_COVER_CHUNK", 37)  # the coverage check split too
    monkeypatch.setattr(fusion_module, "_MERGE_CHUNK", 29)  # and the geometry merge
    monkeypatch.setattr("numba.config.NUMBA_NUM_THREADS", 9)
    stats = fmap.integrate(rgb, depth, K, pose, pf)
    monkeypatch.setattr("numba.config.NUMBA_NUM_THREADS", 1)
    assert one.integrate(rgb, depth, K, pose, pf) == stats
    _assert_same_state(fmap, one)


def test_merged_nearest_point_follows_float32_rounding():
    # One scan keeps the nearest depth rounded to float32 and replaces it only by a strictly
    # smaller exact depth. Range A's point sits at z1, kept as f32(z1) < z1; range B's point at
    # z2 with f32(z1) < z2 < z1 does not replace it, although it is nearer.
    z1 = 1.0 + 3e-8
    kept = np.float32(z1)
    assert float(kept) < z1
    z2 = (float(kept) + z1) / 2
    none = np.full(1, -1, np.int32), np.zeros(1, np.float32), np.zeros(1, np.float32)
    a = (*none, np.array([0], np.int32), np.array([kept], np.float32), np.array([z1]))
    b = (*none, np.array([1], np.int32), np.array([np.float32(z2)], np.float32), np.array([z2]))
    _association.merge_scans(*a, *b)
    assert a[3][0] == 0 and a[4][0] == kept
    c = (*none, np.array([2], np.int32), np.array([np.float32(0.5)], np.float32), np.array([0.5]))
    _association.merge_scans(*a, *c)  # strictly nearer than the kept depth: replaces it
    assert a[3][0] == 2 and a[4][0] == np.float32(0.5)


def test_the_maps_products_run_on_one_blas_thread_and_the_count_comes_back():
    import subprocess
    import sys

    code = (
        "import numpy, threadpoolctl\n"
        "import conceptfusion.map.feature_store as fs\n"
        "def blas():\n"
        "    return sorted({i['num_threads'] for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas'})\n"
        "seen = []\n"
        "class Bank(numpy.ndarray):\n"
        "    def __matmul__(self, other):\n"
        "        seen.append(blas()[0])\n"
        "        return numpy.asarray(self) @ other\n"
        "store = fs.FeatureStore(4)\n"
        "store._bank = numpy.eye(4, dtype=numpy.float32).view(Bank)\n"
        "store._num_bank = 4\n"
        "store.scores(numpy.ones(4, numpy.float32), 0)\n"
        "print(blas(), seen)\n"
    )
    env = {**__import__("os").environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[2] [1]", out.stdout
