"""Saving, loading and exporting maps.

A map file is an uncompressed ``.npz`` archive holding a JSON header (format name, format
version, parameters, sizes) and the map's arrays: positions, normals, colours, confidences
and the feature store, so fusion continues exactly where it stopped after a reload. Since
format version 2 the header may also say how the map was made and is meant to be asked
(``meta``: the encoder spec, the proposer, the score floor, the lookup its agent used), which
:func:`read_map_meta` reads without loading the arrays; the viewer opens a map with them. Files are
written atomically. A file from a newer format version is refused with
:class:`~conceptfusion.errors.MapVersionError`; a truncated, corrupt or foreign file with
:class:`~conceptfusion.errors.MapFormatError`.
"""

from __future__ import annotations

import io
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from conceptfusion.array_files import check_npz_headers
from conceptfusion.errors import MapFormatError, MapVersionError, MissingFileError
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.io_utils import atomic_write_bytes

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "META_KEYS", "save_map", "load_map", "read_map_meta", "export_ply",
           "heatmap_colors"]

FORMAT_NAME = "conceptfusion-map"
FORMAT_VERSION = 2
"""Version 2 added the optional ``meta`` header field; version 1 files read as before."""

META_KEYS = {
    "encoder": str, "proposer": str, "setting": str, "min_score": (int, float, type(None)), "lookup": str,
    "name_only": bool, "agent": str,
}
"""What a map file's ``meta`` may say, and its type: ``encoder`` the perception spec the map was
built with (``"embedded-v2"``, ``"onnx:DIR"`` ...), ``proposer`` the mask proposer, ``setting``
the score-floor setting (``"tabletop"``, ``"household"``, ``"search"``), ``min_score`` the floor
itself (None: none), ``lookup`` how its agent asked it (``"plain"``: :meth:`ConceptMapper.locate`;
``"present"``: :meth:`ConceptMapper.locate_present`, which presumes a named object is there),
``name_only`` the name-only last resort of that lookup, ``agent`` the agent's name."""
LOOKUPS = ("plain", "present")

_EXPECTED = {
    # name: (dtype kind, ndim, rows are points?)
    "geometry": ("f", 2, True),
    "feat_bank": ("f", 2, False),
    "feat_point_ids": ("i", 2, True),
    "feat_point_w": ("f", 2, True),
    "feat_point_gram": ("f", 2, True),
    "feat_point_sq": ("f", 1, True),
}


def save_map(map_: PointFusionMap, path: str | os.PathLike, *, meta: dict | None = None) -> Path:
    """Write a map to ``path`` (``.npz``) atomically; returns the path.

    ``meta``: how the map was made and is meant to be asked (keys of :data:`META_KEYS`, each
    optional); the viewer opens the map with them, so its answers are the ones the map's agent saw.

    Example::

        from conceptfusion import load_map, save_map

        save_map(mapper.map, "runs/mine/scene.map.npz")   # then: cfharness view runs/mine/scene.map.npz
        same = load_map("runs/mine/scene.map.npz")
    """
    header, arrays = map_.state_dict()
    header = {"format": FORMAT_NAME, "version": FORMAT_VERSION, **header}
    if meta:
        header["meta"] = _check_meta(meta, "save_map: meta")
    buf = io.BytesIO()
    np.savez(buf, header=np.frombuffer(json.dumps(header).encode("utf-8"), np.uint8), **arrays)
    return atomic_write_bytes(path, buf.getvalue())


_ZIP_MAGIC = b"PK\x03\x04"
_NPY_MAGIC = b"\x93NUMPY"
_HEADER_KEYS = {"format": str, "version": int, "feature_dim": int, "num_points": int, "frames_integrated": int, "config": dict}
_CONFIG_KEYS = ("dist_th", "angle_th_deg", "sigma", "max_depth", "slots")
_GEO_COLS = 10  # position (3), normal (3), colour (3), confidence (1); see PointFusionMap.state_dict


def _check_meta(meta, where: str) -> dict:
    """``meta`` when it is a dict of :data:`META_KEYS` with values of their types; ``ValueError``
    naming the key otherwise."""
    if not isinstance(meta, dict):
        raise ValueError(f"{where}: expected a dict, got {type(meta).__name__}")
    unknown = sorted(set(meta) - set(META_KEYS))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; expected some of {sorted(META_KEYS)}")
    for key, value in meta.items():
        kind = META_KEYS[key]
        if isinstance(value, bool) and kind is not bool or not isinstance(value, kind):
            names = " or ".join(k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,)))
            raise ValueError(f"{where}: {key!r} expected {names}, got {value!r}")
    if meta.get("lookup") is not None and meta["lookup"] not in LOOKUPS:
        raise ValueError(f"{where}: 'lookup' expected one of {list(LOOKUPS)}, got {meta['lookup']!r}")
    return dict(meta)


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def load_map(path: str | os.PathLike) -> PointFusionMap:
    """Read a map written by :func:`save_map`.

    Raises :class:`~conceptfusion.errors.MissingFileError` (a ``FileNotFoundError``) when there
    is no such file, :class:`~conceptfusion.errors.MapVersionError` for a newer format version,
    and :class:`~conceptfusion.errors.MapFormatError` naming the file and what is wrong for
    anything else: not an ``.npz`` archive (a ``.npy`` array, a text file), truncated or corrupt,
    an array header that claims more (or fewer) elements than its member holds (checked before
    anything is allocated: :func:`~conceptfusion.array_files.check_npz_headers`),
    another format, a header field missing, unknown or of the wrong type, arrays of the wrong
    dtype or shape, NaN or infinite values, or feature rows that do not exist.

    Example::

        from conceptfusion import load_map

        fmap = load_map("runs/demo/map.npz")
        print(len(fmap), fmap.feature_dim)   # points, concept-vector dimension
    """
    p = Path(path)
    _check_file(p)
    try:
        check_npz_headers(p, MapFormatError, what="map file")  # before np.load allocates what headers claim
        with np.load(p, allow_pickle=False) as z:
            if "header" not in z.files:
                raise MapFormatError(f"{p}: expected a '{FORMAT_NAME}' file with a header, found entries {z.files[:8]}")
            raw = z["header"]
            arrays = {name: z[name] for name in z.files if name != "header"}
    except MapFormatError:
        raise
    except ValueError as exc:
        if "pickle" in str(exc):  # numpy's text would suggest allow_pickle=True: never for a map
            raise MapFormatError(f"{p}: not a readable map file: an entry holds Python objects, which a map never "
                                 "does") from None
        raise MapFormatError(f"{p}: not a readable map file (truncated or corrupt?): {exc}") from exc
    except (zipfile.BadZipFile, EOFError, OSError, KeyError) as exc:
        raise MapFormatError(f"{p}: not a readable map file (truncated or corrupt?): {exc}") from exc
    header = _parse_header(p, raw)
    _validate_header(p, header)
    _validate(p, header, arrays)
    try:
        return PointFusionMap.from_state_dict(header, arrays)
    except (TypeError, ValueError) as exc:  # a safety net: the checks above should have caught it
        raise MapFormatError(f"{p}: not a valid map: {exc}") from exc


def _check_file(p: Path) -> None:
    """Refuse what cannot be a map file: missing, a folder, a ``.npy`` array, not a zip archive."""
    if not p.is_file():
        if p.exists():
            raise MapFormatError(f"{p}: expected a map file, got a {'folder' if p.is_dir() else 'special file'}")
        raise MissingFileError(f"map file not found: {p}")
    with open(p, "rb") as f:
        head = f.read(8)
    if head.startswith(_NPY_MAGIC):
        raise MapFormatError(f"{p}: not a readable map file: this is a single-array .npy file; a map is an .npz "
                             "archive written by save_map")
    if not head.startswith(_ZIP_MAGIC):
        raise MapFormatError(f"{p}: not a readable map file: expected an .npz archive written by save_map, but the "
                             f"file starts with {head!r}" if head else f"{p}: not a readable map file: the file is empty")


def _parse_header(p: Path, raw: np.ndarray) -> dict:
    """The JSON header of a map file, its format and version checked (not yet its fields)."""
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise MapFormatError(f"{p}: header: expected JSON text as a 1-D uint8 array, got {raw.dtype}, shape {raw.shape}")
    try:
        header = json.loads(raw.tobytes().decode("utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise MapFormatError(f"{p}: header: not valid JSON text: {exc}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise MapFormatError(f"{p}: expected format '{FORMAT_NAME}', got {got!r}")
    version = header.get("version")
    if not _is_int(version) or version < 1:
        raise MapFormatError(f"{p}: expected an integer format version >= 1, got {version!r}")
    if version > FORMAT_VERSION:
        raise MapVersionError(
            f"{p}: written by format version {version}; this code reads versions up to {FORMAT_VERSION} "
            "(upgrade the package to read it)"
        )
    return header


def read_map_meta(path: str | os.PathLike) -> dict:
    """The ``meta`` of a map file (see :data:`META_KEYS`): ``{}`` for a file that records none
    (format version 1). Reads the header only, not the arrays.

    Example::

        from conceptfusion.map.persistence import read_map_meta

        read_map_meta("runs/main/replays/search__map-navigator__search-v2-0003__s0.map.npz")
        # {'encoder': 'embedded-v2', 'proposer': 'rgbd', 'setting': 'search', 'lookup': 'plain', ...}

    Raises:
        MissingFileError, MapFormatError, MapVersionError: as :func:`load_map`, for the header.
    """
    p = Path(path)
    _check_file(p)
    try:
        with zipfile.ZipFile(p) as z:
            if "header.npy" not in z.namelist():
                raise MapFormatError(f"{p}: expected a '{FORMAT_NAME}' file with a header, found entries {z.namelist()[:8]}")
            with z.open("header.npy") as f:
                raw = np.lib.format.read_array(f, allow_pickle=False)
    except MapFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise MapFormatError(f"{p}: not a readable map file (truncated or corrupt?): {exc}") from exc
    header = _parse_header(p, raw)
    try:
        return _check_meta(header.get("meta", {}), "header field 'meta'")
    except ValueError as exc:
        raise MapFormatError(f"{p}: {exc}") from None


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def _validate_header(p: Path, header: dict) -> None:
    for key, kind in _HEADER_KEYS.items():
        if key not in header:
            raise MapFormatError(f"{p}: header lacks the field {key!r}")
        v = header[key]
        if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
            raise MapFormatError(f"{p}: header field {key!r}: expected {kind.__name__}, got {v!r}")
    optional = {"meta"} if header["version"] >= 2 else set()
    unknown = sorted(set(header) - set(_HEADER_KEYS) - optional)
    if unknown:
        raise MapFormatError(f"{p}: header: unknown field(s) {unknown}; expected {sorted(_HEADER_KEYS)}"
                             + (" and optionally 'meta'" if optional else ""))
    if "meta" in header:
        try:
            _check_meta(header["meta"], "header field 'meta'")
        except ValueError as exc:
            raise MapFormatError(f"{p}: {exc}") from None
    for key in ("num_points", "frames_integrated"):
        if header[key] < 0:
            raise MapFormatError(f"{p}: header field {key!r}: expected >= 0, got {header[key]}")
    if header["feature_dim"] < 1:
        raise MapFormatError(f"{p}: header field 'feature_dim': expected >= 1, got {header['feature_dim']}")
    cfg = header["config"]
    missing, unknown = [k for k in _CONFIG_KEYS if k not in cfg], sorted(set(cfg) - set(_CONFIG_KEYS))
    if missing or unknown:
        raise MapFormatError(f"{p}: header field 'config': expected the keys {list(_CONFIG_KEYS)}"
                             + (f"; missing {missing}" if missing else "") + (f"; unknown {unknown}" if unknown else ""))
    for key in _CONFIG_KEYS:
        v = cfg[key]
        if key == "max_depth" and v is None:  # None stands for infinity
            continue
        if key == "slots":
            ok = _is_int(v) and v >= 1
        else:
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
        if not ok:
            what = "an integer >= 1" if key == "slots" else "a positive finite number" + (" or null" if key == "max_depth" else "")
            raise MapFormatError(f"{p}: header field 'config.{key}': expected {what}, got {v!r}")
    if not cfg["angle_th_deg"] <= 180:
        raise MapFormatError(f"{p}: header field 'config.angle_th_deg': expected a value in (0, 180], got {cfg['angle_th_deg']!r}")


def _validate(p: Path, header: dict, arrays: dict[str, np.ndarray]) -> None:
    n, d, slots = header["num_points"], header["feature_dim"], header["config"]["slots"]
    for name, (kind, ndim, per_point) in _EXPECTED.items():
        if name not in arrays:
            raise MapFormatError(f"{p}: expected array '{name}', file has {sorted(arrays)}")
        a = arrays[name]
        if a.dtype.kind != kind or a.ndim != ndim or (per_point and a.shape[0] != n):
            raise MapFormatError(
                f"{p}: array '{name}' expected kind '{kind}', {ndim} dims"
                + (f", {n} rows" if per_point else "")
                + f"; got {a.dtype}, shape {a.shape}"
            )
    unknown = sorted(set(arrays) - set(_EXPECTED))
    if unknown:
        raise MapFormatError(f"{p}: unknown array(s) {unknown}; a map holds {sorted(_EXPECTED)}")
    tri = slots * (slots + 1) // 2
    widths = {"geometry": _GEO_COLS, "feat_bank": d, "feat_point_ids": slots, "feat_point_w": slots, "feat_point_gram": tri}
    for name, width in widths.items():
        if arrays[name].shape[1] != width:
            raise MapFormatError(f"{p}: array '{name}' expected {width} columns (feature_dim={d}, slots={slots}), "
                                 f"got shape {arrays[name].shape}")
    for name, (kind, _, _) in _EXPECTED.items():
        if kind == "f" and not np.isfinite(arrays[name]).all():
            bad = np.argwhere(~np.isfinite(arrays[name]))[0].tolist()
            raise MapFormatError(f"{p}: array '{name}' holds NaN or infinite values (first at index {bad})")
    ids = arrays["feat_point_ids"]
    if ids.size and (ids.min() < -1 or ids.max() >= len(arrays["feat_bank"])):
        raise MapFormatError(f"{p}: points refer to missing feature bank rows")


def heatmap_colors(values_n: np.ndarray, *, nan_color=(128, 128, 128)) -> np.ndarray:
    """Colours for scores in [0, 1]: dark blue (low) through green and yellow to red (high).

    Values are clipped to [0, 1]; NaN gets ``nan_color``.

    Shape:
        (N,) -> (N, 3) uint8.
    """
    stops = np.array(
        [[48, 18, 59], [50, 130, 240], [40, 200, 160], [160, 230, 50], [250, 185, 40], [200, 30, 20]], np.float64
    )
    v = np.asarray(values_n, np.float64)
    nan = ~np.isfinite(v)
    x = np.clip(np.where(nan, 0.0, v), 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(np.floor(x).astype(int), len(stops) - 2)
    t = (x - i)[:, None]
    rgb = (1 - t) * stops[i] + t * stops[i + 1]
    rgb[nan] = nan_color
    return np.rint(rgb).astype(np.uint8)


def export_ply(map_: PointFusionMap, path: str | os.PathLike, *, values_n: np.ndarray | None = None) -> Path:
    """Write the map's points as a PLY point cloud, coloured by RGB or by ``values_n``.

    ``values_n`` (e.g. :func:`conceptfusion.map.query.relative_scores` of a query) are drawn with
    :func:`heatmap_colors`.

    Shape:
        ``values_n`` (N,) or None.
    """
    import trimesh

    if values_n is None:
        colors = map_.colors
    else:
        values = np.asarray(values_n)
        if values.shape != (len(map_),):
            raise ValueError(f"values_n: expected shape ({len(map_)},), got {values.shape}")
        colors = heatmap_colors(values)
    rgba = np.concatenate([colors, np.full((len(colors), 1), 255, np.uint8)], axis=1)
    cloud = trimesh.PointCloud(map_.points.astype(np.float64), colors=rgba)
    return atomic_write_bytes(path, cloud.export(file_type="ply"))
