"""Saving and loading maps: exact round trip, continued fusion, refusing bad files."""

import json

import numpy as np
import pytest
import trimesh

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import MapFormatError, MapVersionError
from conceptfusion.perception.features import PixelFeatures
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import FORMAT_VERSION, export_ply, load_map, read_map_meta, save_map
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes

H, W = 36, 48
K = intrinsics_from_fovy(60.0, W, H)
BOXES = tabletop_boxes()
POSES = orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, 6, sweep_deg=90.0)


def _integrate(fmap, pose):
    f = render_boxes(BOXES, K, pose, H, W)
    # features: one random unit vector per instance, deterministic per pose
    rng = np.random.default_rng(int(abs(pose[0, 3]) * 1000))
    pal = rng.normal(size=(len(BOXES), fmap.feature_dim)).astype(np.float32)
    pal /= np.linalg.norm(pal, axis=1, keepdims=True)
    fmap.integrate(f.rgb, f.depth, K, pose, PixelFeatures(pal, f.segmentation))


def _assert_same(a, b):
    assert len(a) == len(b)
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.normals, b.normals)
    assert np.array_equal(a.colors, b.colors)
    assert np.array_equal(a.confidence, b.confidence)
    assert np.array_equal(a.features(), b.features())
    q = np.ones(a.feature_dim)
    assert np.array_equal(a.scores(q), b.scores(q), equal_nan=True)


def test_round_trip_is_exact_and_fusion_continues(tmp_path):
    full = PointFusionMap(8, slots=3)
    half = PointFusionMap(8, slots=3)
    for pose in POSES[:3]:
        _integrate(full, pose)
        _integrate(half, pose)
    path = save_map(half, tmp_path / "m.npz")
    loaded = load_map(path)
    _assert_same(half, loaded)
    assert loaded.config == half.config and loaded.frames_integrated == 3
    for pose in POSES[3:]:
        _integrate(full, pose)
        _integrate(loaded, pose)
    _assert_same(full, loaded)


def test_no_temporary_files_left_behind(tmp_path):
    fmap = PointFusionMap(8)
    _integrate(fmap, POSES[0])
    save_map(fmap, tmp_path / "m.npz")
    save_map(fmap, tmp_path / "m.npz")  # overwrite
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz"]


def test_truncated_file(tmp_path):
    fmap = PointFusionMap(8)
    _integrate(fmap, POSES[0])
    data = save_map(fmap, tmp_path / "m.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(MapFormatError, match="truncated or corrupt"):
        load_map(tmp_path / "cut.npz")


def test_foreign_files(tmp_path):
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(MapFormatError, match="not a readable map file"):
        load_map(tmp_path / "text.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(MapFormatError, match="with a header"):
        load_map(tmp_path / "other.npz")
    header = json.dumps({"format": "something-else", "version": 1}).encode()
    np.savez(tmp_path / "alien.npz", header=np.frombuffer(header, np.uint8))
    with pytest.raises(MapFormatError, match="expected format 'conceptfusion-map'"):
        load_map(tmp_path / "alien.npz")
    with pytest.raises(FileNotFoundError):
        load_map(tmp_path / "missing.npz")


def _rewrite(path, out, edit_header=None, drop=None):
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(bytes(arrays.pop("header")).decode())
    if edit_header:
        edit_header(header)
    if drop:
        arrays.pop(drop)
    np.savez(out, header=np.frombuffer(json.dumps(header).encode(), np.uint8), **arrays)


def test_newer_version_and_damaged_arrays(tmp_path):
    fmap = PointFusionMap(8)
    _integrate(fmap, POSES[0])
    path = save_map(fmap, tmp_path / "m.npz")
    _rewrite(path, tmp_path / "new.npz", edit_header=lambda h: h.update(version=FORMAT_VERSION + 1))
    with pytest.raises(MapVersionError, match=f"version {FORMAT_VERSION + 1}.*up to {FORMAT_VERSION}"):
        load_map(tmp_path / "new.npz")
    _rewrite(path, tmp_path / "drop.npz", drop="feat_bank")
    with pytest.raises(MapFormatError, match="expected array 'feat_bank'"):
        load_map(tmp_path / "drop.npz")
    _rewrite(path, tmp_path / "count.npz", edit_header=lambda h: h.update(num_points=h["num_points"] + 1))
    with pytest.raises(MapFormatError, match="'geometry'"):
        load_map(tmp_path / "count.npz")


def test_ply_export_rgb_and_heatmap(tmp_path):
    fmap = PointFusionMap(8)
    _integrate(fmap, POSES[0])
    export_ply(fmap, tmp_path / "rgb.ply")
    cloud = trimesh.load(tmp_path / "rgb.ply")
    assert len(cloud.vertices) == len(fmap)
    assert np.allclose(cloud.vertices, fmap.points, atol=1e-6)
    assert np.array_equal(np.asarray(cloud.colors)[:, :3], fmap.colors)
    values = np.linspace(0, 1, len(fmap))
    values[0] = np.nan
    export_ply(fmap, tmp_path / "heat.ply", values_n=values)
    heat = np.asarray(trimesh.load(tmp_path / "heat.ply").colors)[:, :3]
    assert heat[0].tolist() == [128, 128, 128]
    assert heat[-1, 0] > heat[-1, 2] and heat[1, 2] > heat[1, 0]  # high red, low blue
    with pytest.raises(ValueError, match="values_n"):
        export_ply(fmap, tmp_path / "bad.ply", values_n=np.zeros(3))


def test_atomic_writes_get_the_usual_file_mode(tmp_path):
    import os
    import stat

    from conceptfusion.io_utils import atomic_write_text

    mask = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "a.txt", "hello")
    finally:
        os.umask(mask)
    assert path.read_text() == "hello"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def test_meta_round_trip_and_version_1_files(tmp_path):
    """A map records how it was made and asked (``meta``, format 2); a version-1 file reads with
    no meta, and a version-1 header may not carry one."""
    fmap = PointFusionMap(8)
    _integrate(fmap, POSES[0])
    meta = {"encoder": "embedded-v2", "proposer": "rgbd", "setting": "search", "min_score": 0.31, "lookup": "present",
            "name_only": True, "agent": "map-navigator"}
    path = save_map(fmap, tmp_path / "m.npz", meta=meta)
    assert read_map_meta(path) == meta
    _assert_same(load_map(path), fmap)
    assert read_map_meta(save_map(fmap, tmp_path / "plain.npz")) == {}
    _rewrite(tmp_path / "plain.npz", tmp_path / "v1.npz", edit_header=lambda h: h.update(version=1))
    assert read_map_meta(tmp_path / "v1.npz") == {} and len(load_map(tmp_path / "v1.npz")) == len(fmap)
    _rewrite(path, tmp_path / "v1meta.npz", edit_header=lambda h: h.update(version=1))
    with pytest.raises(MapFormatError, match=r"unknown field\(s\) \['meta'\]"):
        load_map(tmp_path / "v1meta.npz")


@pytest.mark.parametrize("meta, match", [
    ({"encoder": 3}, "'encoder' expected str, got 3"),
    ({"lookup": "guess"}, "'lookup' expected one of"),
    ({"name_only": "yes"}, "'name_only' expected bool"),
    ({"min_score": True}, "'min_score' expected"),
    ({"colour": "red"}, r"unknown key\(s\) \['colour'\]"),
])
def test_bad_meta_is_refused_on_save_and_load(tmp_path, meta, match):
    fmap = PointFusionMap(8)
    with pytest.raises(ValueError, match=match):
        save_map(fmap, tmp_path / "m.npz", meta=meta)
    assert not (tmp_path / "m.npz").exists()
    save_map(fmap, tmp_path / "ok.npz", meta={"encoder": "color"})
    _rewrite(tmp_path / "ok.npz", tmp_path / "bad.npz", edit_header=lambda h: h.update(meta=meta))
    for read in (load_map, read_map_meta):
        with pytest.raises(MapFormatError, match=match):
            read(tmp_path / "bad.npz")
