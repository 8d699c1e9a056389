"""PyBullet shapes from the project's asset descriptions, shared by tabletop and household builds.

:func:`mjcf_shapes` reads MJCF geom text (procedural objects, furniture) into shape dicts,
:func:`primitive_shapes` does it for a procedural asset at a size, :func:`compound_shapes` turns
shape dicts into one collision and one visual multi-shape, and :func:`texture_png` writes the
small gradient and checker textures surfaces carry (into the asset cache).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from conceptfusion.io_utils import atomic_write_bytes
from sim_envs.assets.meshes import cache_dir
from sim_envs.assets.objects import get_asset

__all__ = ["texture_png", "mjcf_shapes", "primitive_shapes", "compound_shapes"]


def texture_png(name: str, rgb: tuple[float, float, float], pattern: str = "gradient", size: int = 64) -> str:
    """Path of a small texture PNG in two shades of ``rgb`` (written once into the cache).

    ``pattern``: "gradient" (vertical ramp with a faint weave) or "checker" (8x8 squares).
    """
    if pattern not in ("gradient", "checker"):
        raise ValueError(f"pattern: expected 'gradient' or 'checker', got {pattern!r}")
    r, g, b = rgb
    out = cache_dir() / "textures" / f"{name}_{pattern}_{round(r * 255)}_{round(g * 255)}_{round(b * 255)}_{size}.png"
    if out.exists():
        return str(out)
    import cv2

    lo = np.array(rgb) * 0.75
    hi = np.minimum(1.0, np.array(rgb) * 1.1)
    t = np.linspace(0.0, 1.0, size)[:, None, None]
    if pattern == "gradient":
        weave = 0.04 * ((np.arange(size)[None, :, None] // 4 + np.arange(size)[:, None, None] // 4) % 2)
        img = lo + (hi - lo) * t + weave
    else:
        sq = (np.arange(size)[:, None] // (size // 8) + np.arange(size)[None, :] // (size // 8)) % 2
        img = np.where(sq[..., None] == 1, hi, lo) * np.ones((size, size, 3))
    bgr = (np.clip(img, 0, 1)[..., ::-1] * 255).round().astype(np.uint8)
    ok, buf = cv2.imencode(".png", bgr)
    if not ok:
        raise RuntimeError(f"could not encode texture {name!r}")
    atomic_write_bytes(out, buf.tobytes())
    return str(out)


def _floats(text: str | None, n: int, default) -> np.ndarray:
    return np.asarray(default if text is None else [float(x) for x in text.split()][:n], np.float64)


def _quat_z_to(d: np.ndarray) -> list[float]:
    """xyzw quaternion turning +z onto unit vector ``d``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, d)
    s = np.linalg.norm(axis)
    if s < 1e-9:
        return [0.0, 0.0, 0.0, 1.0] if d[2] > 0 else [1.0, 0.0, 0.0, 0.0]
    angle = math.atan2(s, float(np.dot(z, d)))
    axis = axis / s * math.sin(angle / 2)
    return [*axis, math.cos(angle / 2)]


def mjcf_shapes(geoms_xml: str, where: str) -> list[dict]:
    """MuJoCo primitive geoms (MJCF text) as PyBullet shape arguments.

    Returns one dict per geom with ``shapeType`` and the size keyword (``halfExtents``,
    ``radius``, ``length``), ``pos`` (3,) and ``quat`` (xyzw) in the geoms' frame, and
    ``material`` (the geom's material name, or None). A geom type PyBullet has no counterpart for,
    or a shape without volume (a zero or negative size), raises ``ValueError`` naming ``where``.
    """
    import pybullet as p

    root = ET.fromstring(f"<r>{geoms_xml}</r>")
    shapes = []
    for k, g in enumerate(root):
        kind = g.get("type", "sphere")
        sz = _floats(g.get("size"), 3, [0.0])
        pos = _floats(g.get("pos"), 3, [0.0, 0.0, 0.0])
        quat = [0.0, 0.0, 0.0, 1.0]
        turned = [a for a in ("euler", "quat", "axisangle", "xyaxes", "zaxis") if g.get(a) is not None]
        if turned:
            raise ValueError(f"{where}: geom {k}: orientation attribute {turned[0]!r} is not read; use fromto or an unrotated geom")
        if g.get("fromto") is not None:
            ft = _floats(g.get("fromto"), 6, [0.0] * 6)
            a, b = ft[:3], ft[3:]
            length = float(np.linalg.norm(b - a))
            pos, quat = (a + b) / 2, _quat_z_to((b - a) / max(length, 1e-12))
            half = length / 2
        else:
            half = float(sz[1]) if len(sz) > 1 else 0.0
        mat = g.get("material")
        if kind == "box":
            shape = {"shapeType": p.GEOM_BOX, "halfExtents": list(sz[:3]), "pos": pos, "quat": quat, "material": mat}
            dims = list(sz[:3]) if len(sz) >= 3 else [0.0]
        elif kind == "sphere":
            shape = {"shapeType": p.GEOM_SPHERE, "radius": float(sz[0]), "pos": pos, "quat": quat, "material": mat}
            dims = [float(sz[0])]
        elif kind in ("cylinder", "capsule"):
            t = p.GEOM_CYLINDER if kind == "cylinder" else p.GEOM_CAPSULE
            shape = {"shapeType": t, "radius": float(sz[0]), "length": 2 * half, "pos": pos, "quat": quat, "material": mat}
            dims = [float(sz[0])] + ([2 * half] if kind == "cylinder" else [])
        else:
            raise ValueError(f"{where}: geom {k} type {kind!r} has no PyBullet counterpart (expected box, sphere, cylinder or capsule)")
        if not all(np.isfinite(d) and d > 0 for d in dims):
            raise ValueError(f"{where}: geom {k} ({kind}) has no volume: size {g.get('size') or g.get('fromto')!r}; "
                             "expected positive sizes")
        shapes.append(shape)
    return shapes


def primitive_shapes(asset: str, size) -> list[dict]:
    """The MuJoCo primitive geoms of a procedural asset as PyBullet shape arguments
    (:func:`mjcf_shapes`), in the object frame."""
    return mjcf_shapes(get_asset(asset).geoms(tuple(size), "m"), f"asset {asset!r}")


def compound_shapes(shapes: list[dict], client: int) -> tuple[int, int]:
    """Collision and visual shape ids of a compound of :func:`mjcf_shapes`-style shape dicts."""
    import pybullet as p

    types = [s["shapeType"] for s in shapes]
    common = dict(
        shapeTypes=types,
        halfExtents=[s.get("halfExtents", [0, 0, 0]) for s in shapes],
        radii=[s.get("radius", 0.0) for s in shapes],
        lengths=[s.get("length", 0.0) for s in shapes],
        physicsClientId=client,
    )
    col = p.createCollisionShapeArray(
        collisionFramePositions=[[float(x) for x in s["pos"]] for s in shapes],
        collisionFrameOrientations=[[float(q) for q in s["quat"]] for s in shapes], **common,
    )
    vis = p.createVisualShapeArray(
        visualFramePositions=[[float(x) for x in s["pos"]] for s in shapes],
        visualFrameOrientations=[[float(q) for q in s["quat"]] for s in shapes],
        **common,
    )
    return col, vis
