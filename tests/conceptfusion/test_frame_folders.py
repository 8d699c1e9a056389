"""Reading a user's frame folder (npz per frame, TUM RGB-D): rendered box-scene frames written in
both layouts read back as they were written, and each kind of bad folder is refused with one
error naming the file. The writers here are shared with the ``cfharness map`` and docs tests."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import FrameFolderError, MissingFileError
from conceptfusion.frame_folders import TUM_DEPTH_SCALE, detect_layout, open_frame_folder
from conceptfusion.synthetic import orbit_poses, render_boxes, tabletop_boxes

H, W = 120, 160
T0 = 1305031102.175304
"""First rgb timestamp (TUM's are seconds since 1970)."""


@functools.lru_cache(maxsize=None)
def box_frames(n: int = 4) -> tuple:
    """``n`` rendered views of the tabletop box scene on an orbit (exact depth, OpenCV poses)."""
    K = intrinsics_from_fovy(60.0, W, H)
    return tuple(render_boxes(tabletop_boxes(), K, pose, H, W) for pose in orbit_poses((0.0, 0.0, 0.45), 1.3, 0.8, n))


def write_npz_folder(folder: Path, frames, **arrays_of) -> Path:
    """``frame_000000.npz`` ... holding each frame's rgb, depth (float metres), K, cam_to_world;
    ``arrays_of[i]`` (a dict) replaces or adds arrays of frame ``i`` (``None`` drops one)."""
    folder.mkdir(parents=True, exist_ok=True)
    for i, f in enumerate(frames):
        arrays = {"rgb": f.rgb, "depth": f.depth, "K": f.K, "cam_to_world": f.cam_to_world, **arrays_of.get(f"f{i}", {})}
        np.savez(folder / f"frame_{i:06d}.npz", **{k: v for k, v in arrays.items() if v is not None})
    return folder


def tum_times(n: int) -> np.ndarray:
    return T0 + 0.1 * np.arange(n)


def write_tum_folder(folder: Path, frames, *, camera: dict | None = "default", depth_lag: float = 0.004,
                     pose_lag: float = -0.003) -> Path:
    """A TUM RGB-D folder of ``frames``: rgb/ and depth/ PNGs (16-bit, 5000 per metre, 0 where
    nothing was hit), rgb.txt, depth.txt and groundtruth.txt with depth and poses ``depth_lag``
    and ``pose_lag`` seconds off the rgb timestamps, and camera.json (``camera=None``: none)."""
    (folder / "rgb").mkdir(parents=True, exist_ok=True)
    (folder / "depth").mkdir(exist_ok=True)
    rgb_lines, depth_lines, gt_lines = ["# color images"], ["# depth maps"], ["# timestamp tx ty tz qx qy qz qw"]
    for t, f in zip(tum_times(len(frames)), frames):
        cv2.imwrite(str(folder / "rgb" / f"{t:.6f}.png"), np.ascontiguousarray(f.rgb[:, :, ::-1]))
        depth = np.where(np.isfinite(f.depth), np.round(f.depth * TUM_DEPTH_SCALE), 0).astype(np.uint16)
        cv2.imwrite(str(folder / "depth" / f"{t + depth_lag:.6f}.png"), depth)
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth_lines.append(f"{t + depth_lag:.6f} depth/{t + depth_lag:.6f}.png")
        q = Rotation.from_matrix(f.cam_to_world[:3, :3]).as_quat()  # x y z w
        gt_lines.append(f"{t + pose_lag:.6f} " + " ".join(f"{v:.9f}" for v in (*f.cam_to_world[:3, 3], *q)))
    for name, lines in (("rgb.txt", rgb_lines), ("depth.txt", depth_lines), ("groundtruth.txt", gt_lines)):
        (folder / name).write_text("\n".join(lines) + "\n")
    if camera == "default":
        K = frames[0].K
        camera = {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2]}
    if camera is not None:
        (folder / "camera.json").write_text(json.dumps(camera))
    return folder


def test_npz_frames_read_back_exactly(tmp_path):
    frames = box_frames()
    folder = open_frame_folder(write_npz_folder(tmp_path / "mine", frames))
    assert folder.layout == "npz" and len(folder) == 4 and folder.skipped == 0
    for got, want in zip(folder.frames(), frames):
        assert np.array_equal(got.rgb, want.rgb) and got.depth.dtype == np.float32
        assert np.array_equal(got.depth, want.depth)
        assert np.allclose(got.K, want.K) and np.allclose(got.cam_to_world, want.cam_to_world)


def test_npz_millimetre_depth_with_its_scale_and_every_other_frame(tmp_path):
    frames = box_frames()
    mm = {f"f{i}": {"depth": np.where(np.isfinite(f.depth), np.round(f.depth * 1000), 0).astype(np.uint16),
                    "depth_scale": np.float64(1000.0)} for i, f in enumerate(frames)}
    folder = open_frame_folder(write_npz_folder(tmp_path / "mm", frames, **mm), every=2)
    assert [s.rgb.name for s in folder.sources] == ["frame_000000.npz", "frame_000002.npz"]
    got = next(folder.frames())
    hit = np.isfinite(frames[0].depth)
    assert np.abs(got.depth[hit] - frames[0].depth[hit]).max() <= 0.0005 + 1e-6  # half a millimetre of rounding
    assert np.all(got.depth[~hit] == 0)  # no measurement: zero, skipped by fusion


def test_nan_and_zero_depth_pixels_are_legal(tmp_path):
    f = box_frames()[0]
    depth = f.depth.copy()
    depth[:10] = np.nan
    depth[10:20] = 0.0
    folder = open_frame_folder(write_npz_folder(tmp_path / "holes", [f], f0={"depth": depth}))
    frame = next(folder.frames())
    assert np.isnan(frame.depth[:10]).all() and (frame.depth[10:20] == 0).all()


def test_frames_are_numbered_not_sorted_as_text(tmp_path):
    frames = box_frames()
    folder = write_npz_folder(tmp_path / "n", frames[:2])
    (folder / "frame_000001.npz").rename(folder / "frame_10.npz")
    (folder / "frame_000000.npz").rename(folder / "frame_9.npz")
    assert [s.rgb.name for s in open_frame_folder(folder).sources] == ["frame_9.npz", "frame_10.npz"]


def test_a_tum_folder_pairs_rgb_depth_and_poses_by_time(tmp_path):
    frames = box_frames()
    root = write_tum_folder(tmp_path / "tum", frames)
    with open(root / "rgb.txt", "a") as f:  # an rgb image 5 s after the last depth image and pose: left out
        f.write(f"{T0 + 5:.6f} rgb/{T0:.6f}.png\n")
    folder = open_frame_folder(root)
    assert folder.layout == "tum" and len(folder) == 4 and folder.skipped == 1
    assert [s.time for s in folder.sources] == pytest.approx(list(tum_times(4)))
    for got, want in zip(folder.frames(), frames):
        assert np.array_equal(got.rgb, want.rgb)  # PNG is lossless, BGR on disk
        hit = np.isfinite(want.depth)
        assert np.abs(got.depth[hit] - want.depth[hit]).max() <= 0.5 / TUM_DEPTH_SCALE + 1e-6
        assert np.all(got.depth[~hit] == 0)
        assert np.allclose(got.cam_to_world, want.cam_to_world, atol=1e-7)  # quaternion -> matrix, 9 decimals
        assert np.allclose(got.K, want.K)


def test_tum_intrinsics_given_replace_camera_json_and_every_counts_after_pairing(tmp_path):
    frames = box_frames()
    root = write_tum_folder(tmp_path / "tum", frames, camera=None)
    folder = open_frame_folder(root, intrinsics=(100.0, 101.0, 80.0, 60.0), every=3)
    assert len(folder) == 2 and folder.sources[1].time == pytest.approx(T0 + 0.3)
    assert folder.sources[0].K.tolist() == [[100.0, 0.0, 80.0], [0.0, 101.0, 60.0], [0.0, 0.0, 1.0]]


# -- bad folders: one error naming the file ----------------------------------------------------


def _npz(tmp_path, **arrays_of):
    return write_npz_folder(tmp_path / "frames", box_frames()[:3], **arrays_of), {}


def _tum(tmp_path, **kw):
    return write_tum_folder(tmp_path / "frames", box_frames()[:3], **kw), {}


def _edit(path: Path, line: int, text: str) -> None:
    lines = path.read_text().splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")


def _tum_missing_depth(tmp_path):
    root, kw = _tum(tmp_path)
    (root / "depth" / f"{T0 + 0.1 + 0.004:.6f}.png").unlink()
    return root, kw


def _tum_small_depth(tmp_path):
    root, kw = _tum(tmp_path)
    path = root / "depth" / f"{T0 + 0.1 + 0.004:.6f}.png"
    cv2.imwrite(str(path), np.zeros((60, 80), np.uint16))
    return root, kw


def _tum_8bit_depth(tmp_path):
    root, kw = _tum(tmp_path)
    cv2.imwrite(str(root / "depth" / f"{T0 + 0.004:.6f}.png"), np.zeros((H, W), np.uint8))
    return root, kw


def _tum_gt_line(text):
    def make(tmp_path):
        root, kw = _tum(tmp_path)
        _edit(root / "groundtruth.txt", 3, f"{T0 + 0.1:.6f} {text}")
        return root, kw
    return make


def _tum_camera(camera):
    return lambda tmp_path: _tum(tmp_path, camera=camera)


def _folder_with(*names):
    def make(tmp_path):
        root = tmp_path / "frames"
        root.mkdir()
        for n in names:
            (root / n).write_text("x")
        return root, {}
    return make


def _not_an_archive(tmp_path):
    root, kw = _npz(tmp_path)
    (root / "frame_000002.npz").write_bytes(b"rgb,depth\n")
    return root, kw


def _both_layouts(tmp_path):
    root, kw = _npz(tmp_path)
    (root / "rgb.txt").write_text("")
    return root, kw


_f1 = box_frames()[1]
_scaled = _f1.cam_to_world.copy()
_scaled[:3, :3] *= 1.1
_nan_pose = _f1.cam_to_world.copy()
_nan_pose[0, 3] = np.nan
_K_off = _f1.K.copy()
_K_off[0, 2] = 400.0
_K_neg = _f1.K.copy()
_K_neg[1, 1] = -_K_neg[1, 1]

BAD_FOLDERS = [
    ("npz: missing depth", lambda t: _npz(t, f1={"depth": None}), FrameFolderError,
     r"frame_000001\.npz: no 'depth' array \(a frame file holds rgb, depth, K, cam_to_world.*found K, cam_to_world, rgb\)"),
    ("npz: size mismatch", lambda t: _npz(t, f1={"depth": np.ones((60, 80), np.float32)}), FrameFolderError,
     r"frame_000001\.npz: rgb is 160x120 but depth is 80x60 \(expected the same size"),
    ("npz: non-orthonormal rotation", lambda t: _npz(t, f1={"cam_to_world": _scaled}), FrameFolderError,
     r"frame_000001\.npz: cam_to_world: expected a rigid transform \(orthonormal rotation, det \+1\)"),
    ("npz: NaN pose", lambda t: _npz(t, f1={"cam_to_world": _nan_pose}), FrameFolderError,
     r"frame_000001\.npz: cam_to_world has NaN or infinite values"),
    ("npz: principal point outside", lambda t: _npz(t, f1={"K": _K_off}), FrameFolderError,
     r"frame_000001\.npz: the principal point \(cx, cy\) = \(400, 59\.5\) lies outside the 160x120 image"),
    ("npz: negative focal length", lambda t: _npz(t, f1={"K": _K_neg}), FrameFolderError,
     r"frame_000001\.npz: focal lengths fx = 103\.9\d*, fy = -103\.9\d*: expected positive"),
    ("npz: not an archive", _not_an_archive, FrameFolderError, r"frame_000002\.npz: not a readable \.npz archive"),
    ("npz: integer depth, no scale", lambda t: _npz(t, f2={"depth": np.zeros((H, W), np.uint16)}), FrameFolderError,
     r"frame_000002\.npz: depth is integer-valued without depth_scale"),
    ("tum: missing depth file", _tum_missing_depth, MissingFileError,
     r"depth/1305031102\.279304\.png: no such depth image \(listed in depth\.txt line 3\)"),
    ("tum: size mismatch", _tum_small_depth, FrameFolderError,
     r"depth/1305031102\.279304\.png: the depth image is 80x60 but its rgb image .*rgb/1305031102\.275304\.png is 160x120"),
    ("tum: 8-bit depth", _tum_8bit_depth, FrameFolderError,
     r"depth/1305031102\.179304\.png: expected a 16-bit single-channel depth image .*got 8-bit"),
    ("tum: non-unit quaternion", _tum_gt_line("1 2 1 0.5 0 0 0.5"), FrameFolderError,
     r"groundtruth\.txt:3: the quaternion \(qx qy qz qw\) = \(0\.5 0 0 0\.5\) has norm 0\.7071, so its rotation is not orthonormal"),
    ("tum: NaN pose", _tum_gt_line("nan 2 1 0 0 0 1"), FrameFolderError,
     r"groundtruth\.txt:3: the pose has NaN or infinite values"),
    ("tum: unreadable line", _tum_gt_line("1 2 3"), FrameFolderError,
     r"groundtruth\.txt:3: expected 'timestamp tx ty tz qx qy qz qw', got '1305031102\.275304 1 2 3'"),
    ("tum: principal point outside", _tum_camera({"fx": 100, "fy": 100, "cx": 80, "cy": 500}), FrameFolderError,
     r"frames/camera\.json: the principal point \(cx, cy\) = \(80, 500\) lies outside the 160x120 image"),
    ("tum: zero focal length", _tum_camera({"fx": 0, "fy": 100, "cx": 80, "cy": 60}), FrameFolderError,
     r"frames/camera\.json: focal lengths fx = 0, fy = 100: expected positive"),
    ("tum: no intrinsics", _tum_camera(None), FrameFolderError,
     r"frames: a TUM folder needs its camera's intrinsics: add camera\.json \(\{\"fx\": 525\.0, .*\"cy\": 239\.5\}\) or"),
    ("tum: no groundtruth", _folder_with("rgb.txt", "depth.txt"), MissingFileError,
     r"frames/groundtruth\.txt: missing \(a TUM RGB-D folder has rgb\.txt, depth\.txt and groundtruth\.txt\)"),
    ("empty folder", _folder_with(), FrameFolderError, r"frames: the folder is empty \(expected frame_000000\.npz"),
    ("unknown layout", _folder_with("notes.txt", "000001.npz"), FrameFolderError,
     r"frames: unknown layout: found 000001\.npz, notes\.txt .*must be named frame_NNNNNN\.npz"),
    ("both layouts", _both_layouts, FrameFolderError, r"frames: holds both frame_\*\.npz files and a TUM"),
]
"""(case, make(tmp_path) -> (folder, open_frame_folder keywords), error, message) of bad folders."""


@pytest.mark.parametrize("case, make, error, message", BAD_FOLDERS, ids=[c[0] for c in BAD_FOLDERS])
def test_a_bad_folder_is_refused_naming_the_file(tmp_path, case, make, error, message):
    folder, kwargs = make(tmp_path)
    with pytest.raises(error, match=message) as info:
        open_frame_folder(folder, **kwargs)
    assert "\n" not in str(info.value)


def test_no_tum_frame_paired_within_the_tolerance_is_an_error(tmp_path):
    root, _ = _tum(tmp_path, depth_lag=0.05)
    with pytest.raises(FrameFolderError, match=r"frames: no rgb image has a depth image and a pose within 0\.02 s"):
        open_frame_folder(root)
    assert len(open_frame_folder(root, max_time_diff=0.06)) == 3


def test_the_layout_of_a_file_or_a_missing_folder(tmp_path):
    (tmp_path / "f.npz").write_bytes(b"")
    with pytest.raises(FrameFolderError, match=r"f\.npz: expected a folder of RGB-D frames, got a file"):
        detect_layout(tmp_path / "f.npz")
    with pytest.raises(MissingFileError, match=r"frame folder not found: .*nowhere"):
        detect_layout(tmp_path / "nowhere")
    with pytest.raises(FrameFolderError, match=r"intrinsics are given, but npz frames carry their own K"):
        open_frame_folder(_npz(tmp_path)[0], intrinsics=(1, 1, 1, 1))
