"""Instance meshes as cached files both simulators load: a textured visual OBJ, convex collision
pieces and a texture PNG.

Every file is normalised as :mod:`sim_envs.assets.meshes` does it: z up, centred in x and y,
resting on z = 0, bounding box ``[-0.5, 0.5]^2 x [0, 1]``, so scaling by a size ``(x, y, z)``
gives exactly that bounding box. Collision is a set of convex pieces in the same frame: the hull
of each solid part, and for open vessels (cups, bowls, pots, buckets ...) the hull of the floor
plus hulls of eight wall sectors, so things can stand inside them. Decorative parts (a wick, a
bucket's bail) do not collide.

Files live in ``<cache_dir()>/library/<id>_<key>/`` (``key`` hashes the instance's record and
the generator version) and are written atomically; ``meta.json``, written last, marks an entry
complete, so an interrupted export is redone, never half-read.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from conceptfusion.errors import SimError
from conceptfusion.io_utils import atomic_write_text
from sim_envs.assets.library.catalogue import Instance, get_instance
from sim_envs.assets.library.geometry import MeshData, Part, merge
from sim_envs.assets.library.shapes import build_shape
from sim_envs.assets.library.textures import texture_path
from sim_envs.assets.meshes import cache_dir, mesh_texture, normalized_mesh, pybullet_data_dir

__all__ = ["ExportedInstance", "export_instance", "instance_parts", "instance_size", "GENERATOR_VERSION", "WALL_SECTORS"]

GENERATOR_VERSION = "1"
"""Bumped whenever generated geometry changes, so stale cache entries are not reused."""

WALL_SECTORS = 8
"""Convex pieces an open vessel's wall is cut into."""

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ExportedInstance:
    """The cached files of one instance."""

    instance: Instance
    """What was exported."""
    visual: Path
    """Normalised OBJ with texture coordinates (``v`` and ``vt`` share indices)."""
    hulls: tuple[Path, ...]
    """Normalised convex collision pieces (OBJ)."""
    texture: Path
    """PNG texture."""
    size: tuple[float, float, float]
    """Bounding box (x, y, z) of the instance at its own scale (metres)."""


def instance_parts(inst: Instance) -> list[Part]:
    """The procedural parts of an instance (shape units), checked non-empty."""
    if inst.mesh is not None:
        raise SimError(f"instance {inst.id!r}.variant: a named mesh has no procedural parts")
    return build_shape(inst.variant, inst.param_dict(), where=f"instance {inst.id!r}")


def _hull(points: np.ndarray) -> MeshData | None:
    import trimesh
    from scipy.spatial import QhullError

    pts = np.unique(np.round(points, 6), axis=0)
    if len(pts) < 4:
        return None
    try:
        h = trimesh.convex.convex_hull(pts)
    except QhullError:  # flat piece: give it a hair of thickness
        eps = 1e-3 * np.eye(3)
        h = trimesh.convex.convex_hull(np.concatenate([pts, pts + eps[0], pts + eps[1], pts + eps[2]]))
    if len(h.faces) < 4:
        return None
    v = np.asarray(h.vertices, np.float64)
    return MeshData(v, np.asarray(h.faces, np.int64), np.zeros((len(v), 2)))


def _collision_pieces(part: Part) -> list[np.ndarray]:
    """Point sets whose hulls make the part's collision (shape units)."""
    v = part.mesh.vertices
    if part.collision == "none":
        return []
    if part.collision == "hull":
        return [v]
    z0 = v[:, 2].min()
    floor = v[v[:, 2] <= z0 + part.floor + 1e-9]
    wall = v[v[:, 2] >= z0 + part.floor * 0.5]
    ang = np.arctan2(wall[:, 1] - part.axis_xy[1], wall[:, 0] - part.axis_xy[0])
    pieces = [floor]
    width = 2 * math.pi / WALL_SECTORS
    for k in range(WALL_SECTORS):
        centre = -math.pi + (k + 0.5) * width
        d = np.abs((ang - centre + math.pi) % (2 * math.pi) - math.pi)
        pieces.append(wall[d <= width / 2 + 0.02])
    return pieces


def _obj_text(m: MeshData, header: str, with_uv: bool) -> str:
    lines = [f"# {header}"]
    lines += [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in m.vertices]
    if with_uv:
        lines += [f"vt {a:.6f} {b:.6f}" for a, b in m.uv]
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in m.faces + 1]
    else:
        lines += [f"f {a} {b} {c}" for a, b, c in m.faces + 1]
    return "\n".join(lines) + "\n"


def _entry_dir(inst: Instance) -> Path:
    import hashlib

    key = hashlib.sha1(json.dumps([GENERATOR_VERSION, inst.record()], sort_keys=True).encode()).hexdigest()[:10]
    return cache_dir() / "library" / f"{inst.id}_{key}"


def _read_entry(inst: Instance, folder: Path) -> ExportedInstance | None:
    meta_path = folder / "meta.json"
    if not meta_path.exists():
        return None
    try:
        meta = json.loads(meta_path.read_text())
        files = [folder / meta["visual"], *(folder / h for h in meta["hulls"])]
        texture = Path(meta["texture"])
        size = tuple(float(s) for s in meta["size"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        _log.warning("library cache entry %s is broken (%s); rebuilding it", meta_path, exc)
        return None
    missing = [f for f in [*files, texture] if not f.is_file() or f.stat().st_size == 0]
    if missing:
        _log.warning("library cache entry %s lacks %s; rebuilding it", folder, [str(m) for m in missing])
        return None
    return ExportedInstance(inst, files[0], tuple(files[1:]), texture, size)


def _normalise(v: np.ndarray, lo: np.ndarray, extent: np.ndarray) -> np.ndarray:
    return (v - [(lo[0] + extent[0] / 2), (lo[1] + extent[1] / 2), lo[2]]) / extent


def _export_procedural(inst: Instance, folder: Path) -> tuple[list[str], list[str], Path, np.ndarray]:
    parts = instance_parts(inst)
    visual = merge([p.mesh for p in parts])
    lo, hi = visual.vertices.min(0), visual.vertices.max(0)
    extent = np.maximum(hi - lo, 1e-9)
    size = extent * (inst.scale / extent.max())
    norm = MeshData(_normalise(visual.vertices, lo, extent), visual.faces, visual.uv)
    atomic_write_text(folder / "visual.obj", _obj_text(norm, f"{inst.id}: {inst.variant} (normalised)", True))
    hulls = []
    for part in parts:
        for pts in _collision_pieces(part):
            h = _hull(_normalise(pts, lo, extent)) if len(pts) else None
            if h is not None:
                name = f"hull_{len(hulls):02d}.obj"
                atomic_write_text(folder / name, _obj_text(h, f"{inst.id}: convex piece", False))
                hulls.append(name)
    return ["visual.obj"], hulls, texture_path(inst.material, inst.color), size


def _export_named(inst: Instance, folder: Path) -> tuple[list[str], list[str], Path, np.ndarray]:
    import trimesh

    spec = inst.mesh
    src = pybullet_data_dir() / spec.mesh
    where = f"instance {inst.id!r}.mesh"
    if not src.is_file():
        raise SimError(f"{src}: asset file missing ({where})")
    try:
        visual = normalized_mesh(spec)
        m = trimesh.load(visual, force="mesh", process=False)
        if len(m.faces) == 0:
            raise ValueError("no triangles")
    except SimError:
        raise
    except Exception as exc:  # trimesh raises many kinds on bad files
        raise SimError(f"{src}: asset file broken: {exc} ({where})") from exc
    h = _hull(np.asarray(m.vertices, np.float64))
    if h is None:
        raise SimError(f"{src}: asset file broken: its mesh is degenerate ({where})")
    atomic_write_text(folder / "hull_00.obj", _obj_text(h, f"{inst.id}: convex hull", False))
    tex = mesh_texture(spec) or texture_path(inst.material, inst.color)
    d = np.asarray(spec.default_size, np.float64)
    return [str(visual)], ["hull_00.obj"], tex, d * (inst.scale / d.max())


def export_instance(instance: Instance | str) -> ExportedInstance:
    """The cached files of an instance (an :class:`Instance` or its id), built on first use.

    Raises:
        SimError: a named mesh's source file is missing or unreadable (naming the file and the
            instance field), or a procedural shape is empty.
        UnknownKeyError: an unknown instance id.
    """
    inst = get_instance(instance) if isinstance(instance, str) else instance
    folder = _entry_dir(inst)
    cached = _read_entry(inst, folder)
    if cached is not None:
        return cached
    build = _export_named if inst.mesh is not None else _export_procedural
    visual, hulls, texture, size = build(inst, folder)
    meta = {"instance": inst.record(), "visual": visual[0], "hulls": hulls, "texture": str(texture),
            "size": [round(float(s), 6) for s in size]}
    atomic_write_text(folder / "meta.json", json.dumps(meta, indent=1))
    out = _read_entry(inst, folder)
    if out is None:
        raise SimError(f"{folder}: export of instance {inst.id!r} did not produce its files")
    return out


def instance_size(instance: Instance | str) -> tuple[float, float, float]:
    """Bounding box (x, y, z) in metres of an instance at its own scale (exports it if needed)."""
    return export_instance(instance).size
