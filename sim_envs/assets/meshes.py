"""Mesh object kinds from ``pybullet_data`` (zlib licence), usable in MuJoCo and PyBullet.

Each kind names a mesh file inside ``pybullet_data`` and, where it has one, its texture. The
first use writes a normalised copy into the asset cache (:func:`cache_dir`): an OBJ turned z up,
centred in x and y, resting on z = 0, with a unit bounding box and texture coordinates (meshes
without their own get a cylindrical projection, so the object's paint texture wraps them), and
the texture as a PNG of at most 512 pixels a side. Scaling that unit mesh by the requested size
``(x, y, z)`` gives an object whose bounding box is exactly that size, in both simulators.
Collision is the convex hull of the scaled mesh in both.

MuJoCo declares meshes, textures and materials in ``<asset>``, and a mesh's scale is fixed
there, so a scene with mesh objects needs :func:`mesh_asset_xml` of its ``(kind, size)`` pairs
inside its ``<asset>`` element; the geoms of :func:`mesh_geoms` refer to those names.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from conceptfusion.errors import UnknownKeyError
from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text
from conceptfusion.names import unknown_name_error

__all__ = [
    "MeshKind",
    "MESH_KINDS",
    "cache_dir",
    "pybullet_data_dir",
    "normalized_mesh",
    "mesh_texture",
    "mesh_name",
    "mesh_geoms",
    "mesh_asset_xml",
]

_CACHE_VERSION = "1"


@dataclass(frozen=True)
class MeshKind:
    """A mesh object kind."""

    category: str
    """What it is ("duck", "mug", ...)."""
    phrases: tuple[str, ...]
    """Descriptions that hold for every instance ("a rubber duck", "a toy")."""
    default_size: tuple[float, float, float]
    """Bounding box (x, y, z) in metres at the mesh's own proportions."""
    mesh: str
    """Mesh file, relative to ``pybullet_data``."""
    texture: str | None
    """Texture image relative to ``pybullet_data``; None: painted with the object's colour."""
    up_axis: str
    """The mesh file's up axis, "y" or "z"."""
    native_color: str | None = None
    """The colour name (of ``COLORS``) its own texture looks like; None when painted."""


MESH_KINDS: dict[str, MeshKind] = {
    "duck": MeshKind("duck", ("a rubber duck", "a toy"), (0.099, 0.069, 0.092), "duck.obj", "duckCM.png", "y", "yellow"),
    "teddy": MeshKind("teddy bear", ("a teddy bear", "a soft toy"), (0.076, 0.063, 0.093), "teddy2_VHACD_CHs.obj", None, "y"),
    "soccer_ball": MeshKind("soccer ball", ("a soccer ball", "a ball to play with"), (0.12, 0.12, 0.12), "soccerball.obj", "colors16.png", "z", "white"),
    "lego": MeshKind("lego brick", ("a lego brick", "a toy building block"), (0.063, 0.064, 0.046), "lego/lego.obj", None, "y"),
    "jenga": MeshKind("jenga block", ("a jenga block", "a wooden block"), (0.15, 0.05, 0.03), "jenga/jenga.obj", "jenga/jenga.png", "z", "orange"),
    "mesh_mug": MeshKind("mug", ("a coffee mug", "a cup to drink from"), (0.082, 0.122, 0.10), "objects/mug.obj", None, "z"),
    "tray": MeshKind("tray", ("a tray", "something to carry things on"), (0.30, 0.30, 0.069), "tray/tray_textured2.obj", "tray/tray.jpg", "z", "white"),
}
"""Mesh kinds by asset name (``mesh_mug`` keeps the procedural ``mug`` name free)."""


def cache_dir() -> Path:
    """Folder of generated asset files: ``$CF_ASSET_CACHE``, else ``~/.cache/conceptfusion-harness``."""
    root = os.environ.get("CF_ASSET_CACHE")
    if root:
        return Path(root)
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    return base / "conceptfusion-harness"


def pybullet_data_dir() -> Path:
    """The installed ``pybullet_data`` folder."""
    import pybullet_data

    return Path(pybullet_data.getDataPath())


def _kind(kind: str | MeshKind) -> MeshKind:
    if isinstance(kind, MeshKind):
        return kind
    if kind not in MESH_KINDS:
        raise unknown_name_error("mesh kind", kind, MESH_KINDS, cutoff=0.6, listing=f"known: {sorted(MESH_KINDS)}",
                                 error=UnknownKeyError)
    return MESH_KINDS[kind]


def _label(kind: str | MeshKind) -> str:
    """File-name stem of a kind: its name, or for a :class:`MeshKind` given directly its mesh file's stem."""
    return Path(kind.mesh).stem if isinstance(kind, MeshKind) else kind


def _cache_path(kind: str | MeshKind, suffix: str) -> Path:
    spec = _kind(kind)
    key = hashlib.sha1(f"{_CACHE_VERSION}|{spec.mesh}|{spec.texture}|{spec.up_axis}".encode()).hexdigest()[:10]
    return cache_dir() / "meshes" / f"{_label(kind)}_{key}{suffix}"


def normalized_mesh(kind: str | MeshKind) -> Path:
    """Path of the normalised OBJ of a mesh kind (written on first use, atomically).

    ``kind``: a key of :data:`MESH_KINDS`, or a :class:`MeshKind` of another ``pybullet_data``
    mesh (the object library's extra named meshes). The mesh is z up, its bounding box is
    ``[-0.5, 0.5] x [-0.5, 0.5] x [0, 1]``, and every vertex has a texture coordinate (same
    index for ``v`` and ``vt``).
    """
    out = _cache_path(kind, ".obj")
    if out.exists():
        return out
    import trimesh

    spec = _kind(kind)
    src = pybullet_data_dir() / spec.mesh
    mesh = trimesh.load(src, force="mesh", process=False)
    v = np.asarray(mesh.vertices, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
    uv = getattr(mesh.visual, "uv", None)
    if spec.up_axis == "y":  # rotate +90 degrees about x: y up becomes z up
        v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    lo, hi = v.min(0), v.max(0)
    v = (v - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) / (hi - lo)
    if uv is None or len(uv) != len(v):  # cylindrical projection around z
        uv = np.stack([np.arctan2(v[:, 1], v[:, 0]) / (2 * np.pi) + 0.5, v[:, 2]], axis=1)
    lines = [f"# {_label(kind)}: normalised from pybullet_data/{spec.mesh}"]
    lines += [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v]
    lines += [f"vt {a:.6f} {b:.6f}" for a, b in np.asarray(uv, np.float64)[:, :2]]
    lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in faces + 1]
    atomic_write_text(out, "\n".join(lines) + "\n")
    return out


def mesh_texture(kind: str | MeshKind) -> Path | None:
    """PNG texture of a mesh kind (a name or a :class:`MeshKind`; at most 512 px a side;
    written on first use), or None."""
    spec = _kind(kind)
    if spec.texture is None:
        return None
    out = _cache_path(kind, ".png")
    if out.exists():
        return out
    import cv2

    img = cv2.imread(str(pybullet_data_dir() / spec.texture), cv2.IMREAD_COLOR)
    if img is None:
        raise FileNotFoundError(f"texture of mesh kind {_label(kind)!r} not readable: {pybullet_data_dir() / spec.texture}")
    scale = 512 / max(img.shape[:2])
    if scale < 1:
        img = cv2.resize(img, (round(img.shape[1] * scale), round(img.shape[0] * scale)), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise RuntimeError(f"could not encode the texture of mesh kind {_label(kind)!r}")
    atomic_write_bytes(out, buf.tobytes())
    return out


def mesh_name(kind: str, size) -> str:
    """MJCF name of the mesh asset of ``kind`` scaled to ``size`` (x, y, z metres)."""
    _kind(kind)
    sx, sy, sz = (float(s) for s in size)
    return f"mesh_{kind}_{round(sx * 1e4)}_{round(sy * 1e4)}_{round(sz * 1e4)}"


def mesh_geoms(kind: str, size, material: str) -> str:
    """MJCF geom of a mesh object in its body frame (z up, resting on z = 0).

    Textured kinds use their own material (declared by :func:`mesh_asset_xml`) and ignore
    ``material``; painted kinds use ``material``.
    """
    spec = _kind(kind)
    mat = f"mat_mesh_{kind}" if spec.texture else material
    return f'<geom type="mesh" mesh="{mesh_name(kind, size)}" material="{mat}"/>'


def mesh_asset_xml(items: Iterable) -> str:
    """The ``<asset>`` children a MuJoCo scene with mesh objects must declare.

    Args:
        items: mesh kinds (default size) or ``(kind, size)`` pairs, e.g.
            ``[(o.asset, o.size) for o in scene.objects if o.asset in MESH_KINDS]``.
            Duplicates are declared once.

    Returns:
        MJCF text: one ``<mesh>`` per distinct (kind, size), plus a ``<texture>`` and a
        ``<material>`` per textured kind. Paths are absolute, so no ``meshdir`` is needed.
    """
    meshes: dict[str, str] = {}
    textured: dict[str, str] = {}
    for item in items:
        kind, size = (item, None) if isinstance(item, str) else (item[0], item[1])
        spec = _kind(kind)
        size = spec.default_size if size is None else tuple(float(s) for s in size)
        if len(size) != 3 or min(size) <= 0:
            raise ValueError(f"mesh_asset_xml: expected a positive (x, y, z) size for {kind!r}, got {size}")
        name = mesh_name(kind, size)
        meshes[name] = f'<mesh name="{name}" file="{normalized_mesh(kind)}" scale="{size[0]:.5f} {size[1]:.5f} {size[2]:.5f}"/>'
        tex = mesh_texture(kind)
        if tex is not None and kind not in textured:
            textured[kind] = (
                f'<texture name="tex_mesh_{kind}" type="2d" file="{tex}"/>'
                f'<material name="mat_mesh_{kind}" texture="tex_mesh_{kind}" specular="0.2" shininess="0.2"/>'
            )
    return "".join(meshes.values()) + "".join(textured.values())
