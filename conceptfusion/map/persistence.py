"""Saving, loading and exporting maps.

A map file is an uncompressed ``.npz`` archive holding a JSON header (format name, format
version, parameters, sizes) and the map's arrays: positions, normals, colours, confidences
and the feature store, so fusion continues exactly where it stopped after a reload. Files are
written atomically. A file from a newer format version is refused with
:class:`~conceptfusion.errors.MapVersionError`; a truncated, corrupt or foreign file with
:class:`~conceptfusion.errors.MapFormatError`.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from conceptfusion.errors import MapFormatError, MapVersionError
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.io_utils import atomic_write_bytes

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "save_map", "load_map", "export_ply", "heatmap_colors"]

FORMAT_NAME = "conceptfusion-map"
FORMAT_VERSION = 1

_EXPECTED = {
    # name: (dtype kind, ndim, rows are points?)
    "geometry": ("f", 2, True),
    "feat_bank": ("f", 2, False),
    "feat_point_ids": ("i", 2, True),
    "feat_point_w": ("f", 2, True),
    "feat_point_gram": ("f", 2, True),
    "feat_point_sq": ("f", 1, True),
}


def save_map(map_: PointFusionMap, path: str | os.PathLike) -> Path:
    """Write a map to ``path`` (``.npz``) atomically; returns the path."""
    header, arrays = map_.state_dict()
    header = {"format": FORMAT_NAME, "version": FORMAT_VERSION, **header}
    buf = io.BytesIO()
    np.savez(buf, header=np.frombuffer(json.dumps(header).encode("utf-8"), np.uint8), **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def load_map(path: str | os.PathLike) -> PointFusionMap:
    """Read a map written by :func:`save_map`."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"map file not found: {p}")
    try:
        with np.load(p, allow_pickle=False) as z:
            if "header" not in z.files:
                raise MapFormatError(f"{p}: expected a '{FORMAT_NAME}' file with a header, found entries {z.files[:8]}")
            header = json.loads(bytes(z["header"]).decode("utf-8"))
            arrays = {name: z[name] for name in z.files if name != "header"}
    except MapFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"{p}: not a readable map file (truncated or corrupt?): {exc}") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise MapFormatError(f"{p}: expected format '{FORMAT_NAME}', got {got!r}")
    version = header.get("version")
    if not isinstance(version, int) or version < 1:
        raise MapFormatError(f"{p}: expected an integer format version >= 1, got {version!r}")
    if version > FORMAT_VERSION:
        raise MapVersionError(
            f"{p}: written by format version {version}; this code reads versions up to {FORMAT_VERSION} "
            "(upgrade the package to read it)"
        )
    _validate(p, header, arrays)
    return PointFusionMap.from_state_dict(header, arrays)


def _validate(p: Path, header: dict, arrays: dict[str, np.ndarray]) -> None:
    try:
        n = int(header["num_points"])
        d = int(header["feature_dim"])
        slots = int(header["config"]["slots"])
    except (KeyError, TypeError, ValueError) as exc:
        raise MapFormatError(f"{p}: header lacks a field: {exc}") from exc
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
    tri = slots * (slots + 1) // 2
    if (
        arrays["feat_bank"].shape[1] != d
        or arrays["feat_point_ids"].shape[1] != slots
        or arrays["feat_point_w"].shape[1] != slots
        or arrays["feat_point_gram"].shape[1] != tri
    ):
        raise MapFormatError(f"{p}: feature arrays do not match feature_dim={d}, slots={slots}")
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
