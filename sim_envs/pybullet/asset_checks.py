"""Checks that PyBullet can build every asset of a scene, run before anything is loaded.

PyBullet loads a broken mesh without a word (an OBJ with no faces becomes an empty shape, a flat
collision piece a zero-volume hull that objects fall through) or stops with a bare
``pybullet.error``. :func:`check_pybullet_assets` reads every file a scene would load and every
primitive it would build, and raises :class:`~conceptfusion.errors.SceneFormatError` naming the
scene, the field (``objects[3].asset``, ``furniture[2]``) and the file, before an episode starts.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from conceptfusion.errors import SceneFormatError

__all__ = ["check_pybullet_assets", "mesh_problem", "MIN_HULL_VOLUME"]

MIN_HULL_VOLUME = 1e-9
"""Smallest volume of a collision piece, in the mesh's own (normalised, unit-box) units: below it
the piece is flat or a line, and PyBullet builds a hull nothing collides with."""


def _read_obj(path: Path) -> tuple[np.ndarray, int]:
    """Vertices (N, 3) and face count of an OBJ; ``ValueError`` for a malformed vertex line."""
    verts, faces = [], 0
    with open(path, encoding="utf-8", errors="strict") as fh:
        for n, line in enumerate(fh, 1):
            if line.startswith("v "):
                parts = line.split()[1:4]
                try:
                    verts.append([float(x) for x in parts])
                except ValueError:
                    raise ValueError(f"line {n}: expected 'v x y z', got {line.strip()[:60]!r}") from None
                if len(parts) != 3:
                    raise ValueError(f"line {n}: expected 'v x y z', got {line.strip()[:60]!r}")
            elif line.startswith("f "):
                faces += 1
    return np.asarray(verts, np.float64).reshape(-1, 3), faces


@lru_cache(maxsize=4096)
def _mesh_problem_cached(path: str, mtime_ns: int, size: int, convex: bool) -> str | None:
    try:
        v, faces = _read_obj(Path(path))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        return f"not a readable OBJ mesh ({exc})"
    if len(v) == 0 or faces == 0:
        return f"no geometry ({len(v)} vertices, {faces} faces)"
    if not np.isfinite(v).all():
        return "non-finite vertex coordinates"
    if convex:
        if len(v) < 4:
            return f"a collision piece with {len(v)} vertices has no volume"
        from scipy.spatial import ConvexHull, QhullError

        try:
            volume = ConvexHull(v).volume
        except QhullError:
            volume = 0.0
        if volume < MIN_HULL_VOLUME:
            return f"a collision piece with zero volume ({volume:.2e}; its points are flat or on a line)"
    return None


def mesh_problem(path: str | Path, *, convex: bool) -> str | None:
    """Why PyBullet cannot use the OBJ at ``path`` (None when it can): missing or unreadable,
    no vertices or faces, non-finite coordinates, or, for a ``convex`` collision piece, a hull of
    (nearly) zero volume. Results are cached per file version."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    return _mesh_problem_cached(str(p), st.st_mtime_ns, st.st_size, convex)


def _object_files(o) -> list[tuple[Path, bool]]:
    """(file, is a convex collision piece) of every mesh an object loads in PyBullet."""
    from sim_envs.assets.library.catalogue import is_library_asset
    from sim_envs.assets.library.export import export_instance
    from sim_envs.assets.meshes import normalized_mesh
    from sim_envs.assets.objects import get_asset

    if is_library_asset(o.asset):
        exp = export_instance(o.asset)
        return [(exp.visual, False), *((h, True) for h in exp.hulls)]
    asset = get_asset(o.asset)
    if asset.mesh is not None:
        return [(normalized_mesh(asset.mesh), False)]
    return []


def check_pybullet_assets(scene, source: str | None = None) -> list[list[dict]]:
    """Refuse a scene PyBullet cannot build; return its furniture shapes
    (:func:`~sim_envs.pybullet.household.furniture_shapes`) for the builder to reuse.

    Raises :class:`~conceptfusion.errors.SceneFormatError` whose message starts with ``source``
    (default: the scene id) and names the field and the file: a mesh that is missing, unreadable
    or empty, a collision piece without volume, a primitive with a zero size.
    """
    from sim_envs.pybullet.household import furniture_shapes
    from sim_envs.pybullet.shapes import primitive_shapes

    where = source or f"scene {scene.id!r}"
    for i, o in enumerate(scene.objects):
        field = f"objects[{i}].asset ({o.id!r}: {o.asset!r})"
        for path, convex in _object_files(o):
            problem = mesh_problem(path, convex=convex)
            if problem:
                kind = "collision mesh" if convex else "mesh"
                raise SceneFormatError(f"{where}: {field}: PyBullet cannot load {kind} {path}: {problem}")
        if not _object_files(o):
            try:
                primitive_shapes(o.asset, o.size)
            except ValueError as exc:
                raise SceneFormatError(f"{where}: {field}: PyBullet cannot build it: {exc}") from None
    try:
        return furniture_shapes(scene)
    except ValueError as exc:
        raise SceneFormatError(f"{where}: PyBullet cannot build {exc}") from None
