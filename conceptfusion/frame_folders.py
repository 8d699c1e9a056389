"""Reading a folder of a user's posed RGB-D frames, for ``cfharness map`` and scripts.

Two layouts, told apart by what the folder holds (:func:`detect_layout`):

* ``npz``, one file per frame: ``frame_000000.npz``, ``frame_000001.npz`` ... (in the order of
  their numbers), each holding ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float metres (or an
  integer type with ``depth_scale``, its units per metre: 1000 for millimetres), ``K`` (3, 3)
  and ``cam_to_world`` (4, 4) in the package's convention (:mod:`conceptfusion.cameras`: OpenCV
  camera, x right, y down, z forward; camera-to-world). Other arrays are ignored.
* ``tum``, the TUM RGB-D benchmark's: ``rgb.txt`` and ``depth.txt`` (``timestamp path`` per
  line, ``#`` comments), ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``: the optical
  centre's position and orientation in the world; TUM's camera frame is OpenCV's), the images
  they list (``rgb/*.png`` colour, ``depth/*.png`` 16-bit with :data:`TUM_DEPTH_SCALE` units
  per metre), and the intrinsics: ``camera.json`` (``{"fx": .., "fy": .., "cx": .., "cy": ..}``,
  optionally ``"depth_scale"``) or given. Each rgb image is paired with the depth image and the
  pose nearest in time; an rgb image with either farther than ``max_time_diff`` seconds away is
  skipped (:attr:`FrameFolder.skipped` counts them).

:func:`open_frame_folder` checks every frame it will hand out before any is read in full (array
shapes and dtypes from the files' headers, image sizes, poses, intrinsics), so a bad frame is
refused, naming its file, before a long fusion starts; :meth:`FrameFolder.frames` then reads them.
Depth pixels that are NaN, infinite or zero are legal: no measurement there.

Example::

    from conceptfusion import make_mapper
    from conceptfusion.frame_folders import open_frame_folder

    folder = open_frame_folder("my_frames")           # FrameFolderError naming the bad file
    mapper = make_mapper()
    for frame in folder.frames():
        mapper.integrate(frame)
"""

from __future__ import annotations

import math
import os
import re
import struct
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from conceptfusion.array_files import MAX_NPZ_BYTES, check_npz_headers
from conceptfusion.cameras import check_pose
from conceptfusion.errors import FrameFolderError, MissingFileError, PoseError
from conceptfusion.frames import RGBDFrame
from conceptfusion.io_utils import check_regular_file, read_file_bytes, read_json_file, read_text_file

__all__ = ["LAYOUTS", "TUM_DEPTH_SCALE", "MAX_TIME_DIFF", "FrameSource", "FrameFolder", "detect_layout", "open_frame_folder"]

LAYOUTS = ("npz", "tum")
TUM_DEPTH_SCALE = 5000.0
"""Units per metre of the TUM benchmark's 16-bit depth images."""
MAX_TIME_DIFF = 0.02
"""Seconds an rgb image's depth image and pose may lie from it in time (TUM's own tools' default)."""
MAX_IMAGE_BYTES = 512 * 2**20
"""Largest image file read."""

_NPZ_NAME = re.compile(r"frame_(\d+)\.npz")
_NPZ_KEYS = ("rgb", "depth", "K", "cam_to_world")
_TUM_LISTS = ("rgb.txt", "depth.txt", "groundtruth.txt")
_CAMERA_KEYS = ("fx", "fy", "cx", "cy", "depth_scale")
_PNG = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}
_EXPECTED = ("expected frame_000000.npz, frame_000001.npz ... (rgb, depth, K, cam_to_world each) or a TUM RGB-D "
             "folder (rgb.txt, depth.txt, groundtruth.txt); see docs/mapping.md")


@dataclass(frozen=True)
class FrameSource:
    """Where one checked frame's data lies.

    Shape:
        ``K`` (3, 3) float64, ``cam_to_world`` (4, 4) float64, ``size`` (H, W).
    """

    rgb: Path
    """The rgb image (the frame file in the ``npz`` layout)."""
    depth: Path
    """The depth image (the frame file in the ``npz`` layout)."""
    K: np.ndarray
    cam_to_world: np.ndarray
    depth_scale: float
    """Depth units per metre (1: the depth is in metres)."""
    size: tuple[int, int]
    time: float | None = None
    """The rgb image's timestamp (``tum``), else None."""


@dataclass(frozen=True)
class FrameFolder:
    """A folder of posed RGB-D frames, every one checked (:func:`open_frame_folder`)."""

    path: Path
    layout: str
    """One of :data:`LAYOUTS`."""
    sources: tuple[FrameSource, ...]
    skipped: int = 0
    """rgb images left out for want of a depth image or a pose close enough in time (``tum``)."""

    def __len__(self) -> int:
        return len(self.sources)

    def frames(self) -> Iterator[RGBDFrame]:
        """The frames, read one at a time.

        Shape:
            each: rgb (H, W, 3) uint8, depth (H, W) float32 metres, K (3, 3), cam_to_world (4, 4).

        Raises:
            FrameFolderError: a file that changed since it was checked, or image data that
                cannot be decoded (naming the file).
        """
        read = _read_npz if self.layout == "npz" else _read_tum
        for src in self.sources:
            rgb, depth = read(src)
            if rgb.shape[:2] != src.size or depth.shape != src.size:
                raise FrameFolderError(f"{src.rgb}: holds a {rgb.shape[1]}x{rgb.shape[0]} image with {depth.shape[1]}x"
                                       f"{depth.shape[0]} depth, but its header said {src.size[1]}x{src.size[0]}")
            depth = depth.astype(np.float32) if src.depth_scale == 1.0 else (depth / np.float32(src.depth_scale)).astype(np.float32)
            yield RGBDFrame(rgb=np.ascontiguousarray(rgb), depth=depth, K=src.K, cam_to_world=src.cam_to_world)


def detect_layout(path: str | os.PathLike) -> str:
    """Which of :data:`LAYOUTS` the folder at ``path`` is.

    Raises:
        MissingFileError: no such folder.
        FrameFolderError: not a folder, an empty folder, a folder of neither layout or of both.
    """
    p = Path(path)
    if not p.exists():
        raise MissingFileError(f"frame folder not found: {p}")
    if not p.is_dir():
        raise FrameFolderError(f"{p}: expected a folder of RGB-D frames, got a file ({_EXPECTED})")
    names = sorted(n for n in os.listdir(p) if not n.startswith("."))
    npz = any(_NPZ_NAME.fullmatch(n) for n in names)
    tum = "rgb.txt" in names or "depth.txt" in names
    if npz and tum:
        raise FrameFolderError(f"{p}: holds both frame_*.npz files and a TUM rgb.txt/depth.txt: expected one layout")
    if npz or tum:
        return "npz" if npz else "tum"
    if not names:
        raise FrameFolderError(f"{p}: the folder is empty ({_EXPECTED})")
    hint = "; .npz frame files must be named frame_NNNNNN.npz" if any(n.endswith(".npz") for n in names) else ""
    shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    raise FrameFolderError(f"{p}: unknown layout: found {shown} ({_EXPECTED}){hint}")


def open_frame_folder(path: str | os.PathLike, *, intrinsics: Sequence[float] | None = None, every: int = 1,
                      max_time_diff: float = MAX_TIME_DIFF) -> FrameFolder:
    """The frames of the folder at ``path`` (either layout, see the module docstring), every
    ``every``-th one, each checked before any is read in full.

    Args:
        intrinsics: ``(fx, fy, cx, cy)`` in pixels for a ``tum`` folder (over its
            ``camera.json``); refused for an ``npz`` folder, whose frames carry their ``K``.
        every: keep every ``every``-th frame (1: all), counted after pairing (``tum``).
        max_time_diff: seconds a ``tum`` rgb image's depth image and pose may lie from it.

    Raises:
        MissingFileError: a file that a list names, or a list, is missing (naming it).
        FrameFolderError: naming the file: see :func:`detect_layout`; a frame file without
            ``depth`` (or another array); rgb and depth of different sizes; depth of the wrong
            type or an integer depth without ``depth_scale``; a pose with NaN or infinite values
            or a rotation that is not orthonormal (a non-unit quaternion); intrinsics with a
            focal length that is not positive or a principal point outside the image; list lines
            that cannot be read; no frame left.
    """
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"every: expected an integer >= 1, got {every!r}")
    if not (isinstance(max_time_diff, (int, float)) and math.isfinite(max_time_diff) and max_time_diff > 0):
        raise ValueError(f"max_time_diff: expected a positive number of seconds, got {max_time_diff!r}")
    p = Path(path)
    layout = detect_layout(p)
    if layout == "npz":
        if intrinsics is not None:
            raise FrameFolderError(f"{p}: intrinsics are given, but npz frames carry their own K (given intrinsics are for TUM folders)")
        files = sorted((int(m.group(1)), n) for n in os.listdir(p) if (m := _NPZ_NAME.fullmatch(n)))
        return FrameFolder(p, layout, tuple(_check_npz(p / n) for _, n in files[::every]))
    return _open_tum(p, intrinsics, every, float(max_time_diff))


# -- checks shared by both layouts ------------------------------------------------------------


def _check_intrinsics(K, size: tuple[int, int], where: str) -> np.ndarray:
    K = np.asarray(K, np.float64)
    h, w = size
    if K.shape != (3, 3):
        raise FrameFolderError(f"{where}: K: expected a (3, 3) intrinsics matrix, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise FrameFolderError(f"{where}: K has NaN or infinite values: {K.tolist()}")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise FrameFolderError(f"{where}: focal lengths fx = {K[0, 0]:g}, fy = {K[1, 1]:g}: expected positive pixels")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0:
        raise FrameFolderError(f"{where}: K: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}")
    if not (0.0 <= K[0, 2] <= w and 0.0 <= K[1, 2] <= h):
        raise FrameFolderError(f"{where}: the principal point (cx, cy) = ({K[0, 2]:g}, {K[1, 2]:g}) lies outside the "
                               f"{w}x{h} image (expected 0 <= cx <= {w}, 0 <= cy <= {h}; intrinsics of another image size?)")
    return K


def _check_pose(T, where: str) -> np.ndarray:
    T = np.asarray(T, np.float64)
    if T.shape != (4, 4):
        raise FrameFolderError(f"{where}: cam_to_world: expected a (4, 4) camera-to-world matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise FrameFolderError(f"{where}: cam_to_world has NaN or infinite values (expected a finite rigid pose)")
    try:
        return check_pose(T)
    except PoseError as exc:
        raise FrameFolderError(f"{where}: {str(exc).replace('cam_to_world_44', 'cam_to_world')}") from None


def _check_scale(scale, integer: bool, where: str) -> float:
    if scale is None:
        if integer:
            raise FrameFolderError(f"{where}: depth is integer-valued without depth_scale (expected float metres, or "
                                   "integer depth with depth_scale, its units per metre: 1000 for millimetres)")
        return 1.0
    scale = np.asarray(scale)
    if scale.shape not in ((), (1,)) or scale.dtype.kind not in "fiu" or not np.isfinite(scale).all() or float(scale.ravel()[0]) <= 0:
        raise FrameFolderError(f"{where}: depth_scale: expected one positive number (depth units per metre), got {scale!r:.80}")
    return float(scale.ravel()[0])


# -- npz ---------------------------------------------------------------------------------------


def _check_npz(path: Path) -> FrameSource:
    check_regular_file(path, "frame file", FrameFolderError, MAX_NPZ_BYTES)
    try:
        headers = check_npz_headers(path, FrameFolderError, what="frame file")
    except (zipfile.BadZipFile, OSError) as exc:
        raise FrameFolderError(f"{path}: not a readable .npz archive ({exc})") from None
    arrays = {name[: -len(".npy")]: h for name, h in headers.items() if name.endswith(".npy")}
    missing = [k for k in _NPZ_KEYS if k not in arrays]
    if missing:
        raise FrameFolderError(f"{path}: no {', '.join(repr(k) for k in missing)} array (a frame file holds rgb, depth, K, "
                               f"cam_to_world and, for integer depth, depth_scale; found {', '.join(sorted(arrays)) or 'none'})")
    rgb, depth = arrays["rgb"], arrays["depth"]
    if len(rgb.shape) != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise FrameFolderError(f"{path}: rgb: expected (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
    if len(depth.shape) != 2 or depth.dtype.kind not in "fiu":
        raise FrameFolderError(f"{path}: depth: expected (H, W) float metres or integer with depth_scale, got {depth.shape} {depth.dtype}")
    for key in ("K", "cam_to_world"):
        if arrays[key].dtype.kind not in "fiu":
            raise FrameFolderError(f"{path}: {key}: expected numbers, got {arrays[key].dtype}")
    if depth.shape != rgb.shape[:2]:
        raise FrameFolderError(f"{path}: rgb is {rgb.shape[1]}x{rgb.shape[0]} but depth is {depth.shape[1]}x{depth.shape[0]} "
                               "(expected the same size, depth registered to rgb)")
    with np.load(path, allow_pickle=False) as z:
        K, T = z["K"], z["cam_to_world"]
        scale = z["depth_scale"] if "depth_scale" in arrays else None
    size = (int(depth.shape[0]), int(depth.shape[1]))
    return FrameSource(path, path, _check_intrinsics(K, size, str(path)), _check_pose(T, str(path)),
                       _check_scale(scale, depth.dtype.kind in "iu", str(path)), size)


def _read_npz(src: FrameSource) -> tuple[np.ndarray, np.ndarray]:
    with np.load(src.rgb, allow_pickle=False) as z:
        return z["rgb"], z["depth"]


# -- TUM ---------------------------------------------------------------------------------------


def _read_list(path: Path, columns: int, what: str) -> list[tuple[int, list[float | str]]]:
    """``(line number, fields)`` of a TUM list file: the timestamp, then ``columns - 1`` fields
    (a path for rgb/depth lists, numbers for the ground truth)."""
    rows = []
    for no, line in enumerate(read_text_file(path, what, FrameFolderError).splitlines(), 1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        numeric = columns == 8
        try:
            if len(fields) != columns:
                raise ValueError
            values = [float(f) for f in fields] if numeric else [float(fields[0]), fields[1]]
        except ValueError:
            shape = "timestamp tx ty tz qx qy qz qw" if numeric else "timestamp path"
            raise FrameFolderError(f"{path}:{no}: expected '{shape}', got {line.strip()!r:.100}") from None
        if not math.isfinite(values[0]):
            raise FrameFolderError(f"{path}:{no}: the timestamp is {fields[0]!r}, expected a finite number of seconds")
        rows.append((no, values))
    return rows


def _pose_from_row(values: list[float], where: str) -> np.ndarray:
    t, q = np.array(values[1:4]), np.array(values[4:8])
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise FrameFolderError(f"{where}: the pose has NaN or infinite values (expected tx ty tz qx qy qz qw, finite)")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-3:
        raise FrameFolderError(f"{where}: the quaternion (qx qy qz qw) = ({' '.join(f'{v:g}' for v in q)}) has norm "
                               f"{norm:.4f}, so its rotation is not orthonormal (expected a unit quaternion)")
    x, y, z, w = q / norm
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = t
    return _check_pose(T, where)


def _image_header(path: Path, what: str, listed: str) -> tuple[int, int, int, int]:
    """``(H, W, channels, bits)`` of an image from its header (PNG), else by decoding it."""
    try:
        check_regular_file(path, what, FrameFolderError, MAX_IMAGE_BYTES)
    except MissingFileError:
        raise MissingFileError(f"{path}: no such {what} (listed in {listed})") from None
    with open(path, "rb") as f:
        head = f.read(26)
    if head[:8] == _PNG and head[12:16] == b"IHDR" and len(head) == 26:
        w, h = struct.unpack(">II", head[16:24])
        return h, w, _PNG_CHANNELS.get(head[25], 0), head[24]
    img = _decode(path, what, unchanged=True)
    return img.shape[0], img.shape[1], 1 if img.ndim == 2 else img.shape[2], 16 if img.dtype == np.uint16 else 8


def _decode(path: Path, what: str, *, unchanged: bool) -> np.ndarray:
    import cv2

    data = np.frombuffer(read_file_bytes(path, what, FrameFolderError, MAX_IMAGE_BYTES), np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED if unchanged else cv2.IMREAD_COLOR)
    if img is None:
        raise FrameFolderError(f"{path}: not a readable image (expected the {what} as PNG)")
    return img


def _tum_intrinsics(p: Path, intrinsics: Sequence[float] | None) -> tuple[np.ndarray, float, str]:
    """``(K, depth_scale, where K came from)``."""
    camera = p / "camera.json"
    values = read_json_file(camera, "camera file", FrameFolderError) if camera.exists() else None
    if values is not None:
        if not isinstance(values, dict) or set(values) - set(_CAMERA_KEYS) or not {"fx", "fy", "cx", "cy"} <= set(values) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values.values()):
            raise FrameFolderError(f"{camera}: expected {{\"fx\": .., \"fy\": .., \"cx\": .., \"cy\": ..}} in pixels (and optionally "
                                   f"\"depth_scale\", depth units per metre), got {values!r:.120}")
    scale = _check_scale((values or {}).get("depth_scale", TUM_DEPTH_SCALE), True, str(camera))
    if intrinsics is not None:
        if len(intrinsics) != 4 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in intrinsics):
            raise FrameFolderError(f"intrinsics: expected (fx, fy, cx, cy), got {intrinsics!r}")
        (fx, fy, cx, cy), where = map(float, intrinsics), "the given intrinsics (fx, fy, cx, cy)"
    elif values is not None:
        (fx, fy, cx, cy), where = (float(values[k]) for k in ("fx", "fy", "cx", "cy")), str(camera)
    else:
        raise FrameFolderError(f"{p}: a TUM folder needs its camera's intrinsics: add camera.json ({{\"fx\": 525.0, \"fy\": 525.0, "
                               "\"cx\": 319.5, \"cy\": 239.5}) or give them (cfharness map --intrinsics fx,fy,cx,cy)")
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), scale, where


def _nearest(times: np.ndarray, sorted_times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index into ``sorted_times`` of the nearest to each of ``times``, and the gap (s)."""
    i = np.clip(np.searchsorted(sorted_times, times), 1, len(sorted_times) - 1) if len(sorted_times) > 1 else np.zeros(len(times), int)
    left = np.maximum(i - 1, 0)
    pick = np.where(np.abs(sorted_times[left] - times) <= np.abs(sorted_times[i] - times), left, i)
    return pick, np.abs(sorted_times[pick] - times)


def _open_tum(p: Path, intrinsics, every: int, max_dt: float) -> FrameFolder:
    for name in _TUM_LISTS:
        if not (p / name).is_file():
            raise MissingFileError(f"{p / name}: missing (a TUM RGB-D folder has rgb.txt, depth.txt and groundtruth.txt)")
    rgb_rows = _read_list(p / "rgb.txt", 2, "rgb list")
    depth_rows = _read_list(p / "depth.txt", 2, "depth list")
    gt_rows = _read_list(p / "groundtruth.txt", 8, "ground-truth trajectory")
    for name, rows in zip(_TUM_LISTS, (rgb_rows, depth_rows, gt_rows)):
        if not rows:
            raise FrameFolderError(f"{p / name}: lists nothing (expected one line per {'pose' if name == 'groundtruth.txt' else 'image'})")
    K, scale, k_where = _tum_intrinsics(p, intrinsics)
    poses = [_pose_from_row(v, f"{p / 'groundtruth.txt'}:{no}") for no, v in gt_rows]
    d_order = np.argsort([v[0] for _, v in depth_rows], kind="stable")
    g_order = np.argsort([v[0] for _, v in gt_rows], kind="stable")
    rgb_t = np.array([v[0] for _, v in rgb_rows])
    di, d_gap = _nearest(rgb_t, np.array([depth_rows[k][1][0] for k in d_order]))
    gi, g_gap = _nearest(rgb_t, np.array([gt_rows[k][1][0] for k in g_order]))
    paired = np.flatnonzero((d_gap <= max_dt) & (g_gap <= max_dt))
    if paired.size == 0:
        raise FrameFolderError(f"{p}: no rgb image has a depth image and a pose within {max_dt:g} s (rgb.txt: "
                               f"{rgb_t.min():.3f}..{rgb_t.max():.3f} s; check the timestamps, or allow a larger gap)")
    sources, size = [], None
    for k in paired[::every]:
        (r_no, (t, r_rel)), (d_no, (_, d_rel)) = rgb_rows[k], depth_rows[d_order[di[k]]]
        rgb_path, depth_path = p / r_rel, p / d_rel
        rh, rw, _, _ = _image_header(rgb_path, "rgb image", f"rgb.txt line {r_no}")
        dh, dw, dc, bits = _image_header(depth_path, "depth image", f"depth.txt line {d_no}")
        if dc != 1 or bits != 16:
            raise FrameFolderError(f"{depth_path}: expected a 16-bit single-channel depth image ({scale:g} units per metre), "
                                   f"got {bits}-bit with {dc} channel(s)")
        if (rh, rw) != (dh, dw):
            raise FrameFolderError(f"{depth_path}: the depth image is {dw}x{dh} but its rgb image {rgb_path} is {rw}x{rh} "
                                   "(expected the same size, depth registered to rgb)")
        if size is None:
            size = (rh, rw)
            _check_intrinsics(K, size, k_where)
        elif (rh, rw) != size:
            raise FrameFolderError(f"{rgb_path}: is {rw}x{rh} but the folder's first image is {size[1]}x{size[0]} "
                                   "(one camera for all frames)")
        sources.append(FrameSource(rgb_path, depth_path, K, poses[g_order[gi[k]]], scale, size, float(t)))
    return FrameFolder(p, "tum", tuple(sources), skipped=len(rgb_rows) - int(paired.size))


def _read_tum(src: FrameSource) -> tuple[np.ndarray, np.ndarray]:
    bgr = _decode(src.rgb, "rgb image", unchanged=False)
    depth = _decode(src.depth, "depth image", unchanged=True)
    if depth.dtype != np.uint16 or depth.ndim != 2:
        raise FrameFolderError(f"{src.depth}: expected a 16-bit single-channel depth image, got {depth.dtype} {depth.shape}")
    return bgr[:, :, ::-1], depth
