"""Scans and maps for the map suites: render a shipped scene, fuse a map, label map points.

Shared by :mod:`harness.maps.query`, :mod:`harness.maps.ablation` and :mod:`harness.maps.spatial`.
Everything here is deterministic: a scene id, a trajectory and image size fix the frames.

Label images: every rendered pixel carries one label, objects ``0..n-1`` (the scene's object
order), furniture ``n..n+F-1``, then the table top and legs (``"table"``) and the floor plane
(``"floor"``) of tabletop scenes; -1 elsewhere (walls, room floors, sky). Oracle features read
these labels (privileged), so the oracles also know furniture, the table and the floor: the
``oracle`` by their names, the ``oracle-open`` by their phrases (an object's
:func:`~sim_envs.scenes.descriptions.answer_phrases`; furniture, the table and the floor answer
to their own name, ``"the table"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.scenes.descriptions import answer_phrases
from sim_envs.scenes.episodes import SCENES_ROOT
from sim_envs.scenes.format import Scene, load_scene

__all__ = [
    "SCENE_KINDS", "SceneScan", "shipped_scene_ids", "scene_kind", "load_shipped_scene", "scan_scene", "scan_tabletop",
    "fuse_frames", "point_labels", "scene_label_phrases",
]

SCENE_KINDS = ("tabletop", "household", "tabletop-v2", "household-v2")
"""Kinds of shipped scene, each a folder of ``scenes/`` holding ``<kind>-<number>.json``: the v1
world (primitives) and the v2 world (object library, evaluation seeds only)."""


@dataclass
class SceneScan:
    """A scene, its simulation, its ground truth and the frames of one scan."""

    scene: Scene
    sim: object
    """The :class:`~sim_envs.mujoco.scene.MujocoScene` (for extra views)."""
    frames: list[RGBDFrame]
    """The scan's frames, each with its label image as ``segmentation`` (see the module docstring)."""
    label_names: dict[int, str]
    """Label id -> name (objects, furniture, ``"table"``, ``"floor"``)."""
    object_boxes: np.ndarray
    """Ground-truth object boxes, (n, 2, 3): lower and upper corners."""
    graph: dict
    """The ground-truth scene graph (:func:`sim_envs.scenes.graph.scene_graph`)."""
    geom_labels: np.ndarray
    """Label per geom, (ngeom,) int32."""
    label_phrases: dict[int, list[str]] = field(default_factory=dict)
    """Label id -> every phrase it answers to (objects: their
    :func:`~sim_envs.scenes.descriptions.answer_phrases`; furniture, the table, the floor: their
    name, ``"the table"``), for the ``oracle-open`` perception (privileged)."""

    @property
    def num_objects(self) -> int:
        return len(self.scene.objects)


def shipped_scene_ids(kind: str) -> list[str]:
    """Ids of the shipped scenes of one kind (one of :data:`SCENE_KINDS`), sorted."""
    if kind not in SCENE_KINDS:
        raise ValueError(f"kind: expected one of {SCENE_KINDS}, got {kind!r}")
    return sorted(p.stem for p in (SCENES_ROOT / kind).glob(f"{kind}-*.json") if p.stem[len(kind) + 1:].isdigit())


def scene_kind(scene_id: str) -> str:
    """The kind (:data:`SCENE_KINDS`) of a shipped scene id: ``"tabletop-0111"`` -> ``"tabletop"``,
    ``"household-v2-300000"`` -> ``"household-v2"``; ``ValueError`` for anything else."""
    kind, _, number = str(scene_id).rpartition("-")
    if kind not in SCENE_KINDS or not number.isdigit():
        raise ValueError(f"scene_id: expected '<kind>-<number>' with a kind of {', '.join(SCENE_KINDS)} "
                         f"('tabletop-0111', 'household-v2-300000'), got {scene_id!r}")
    return kind


def load_shipped_scene(scene_id: str) -> Scene:
    """A shipped scene by id (``"tabletop-0111"``, ``"household-0000"``, ``"tabletop-v2-300005"``)."""
    kind = scene_kind(scene_id)
    path = SCENES_ROOT / kind / f"{scene_id}.json"
    if not path.exists():
        raise ValueError(f"scene_id: no shipped scene {scene_id!r} (shipped: {', '.join(shipped_scene_ids(kind)[:5])}, ...)")
    return load_scene(path)


def scene_label_phrases(scene: Scene, label_names: dict[int, str]) -> dict[int, list[str]]:
    """The phrases each label answers to (see :attr:`SceneScan.label_phrases`)."""
    n = len(scene.objects)
    return {k: answer_phrases(scene.objects[k]) if k < n else [f"the {name}"] for k, name in label_names.items()}


def _geom_labels(sim) -> tuple[np.ndarray, dict[int, str]]:
    scene = sim.scene
    labels = np.asarray(sim.geom_labels(), np.int32).copy()
    n, nf = len(scene.objects), len(scene.furniture)
    names = {i: o.name for i, o in enumerate(scene.objects)}
    names.update({n + j: f.name for j, f in enumerate(scene.furniture)})
    if scene.table is not None:
        model = sim.model
        geom_names = [model.geom(g).name for g in range(model.ngeom)]
        table = [g for g, name in enumerate(geom_names) if name == "table_top" or name.startswith("table_leg")]
        floor = [g for g, name in enumerate(geom_names) if name == "floor"]
        labels[table] = n + nf
        names[n + nf] = "table"
        if floor:
            labels[floor] = n + nf + 1
            names[n + nf + 1] = "floor"
    return labels, names


def scan_scene(scene: Scene, *, frames: int, width: int, height: int) -> SceneScan:
    """Render the standard scan of a scene: an orbit around the table (tabletop) or a
    room-by-room sweep (household), ``frames`` frames of ``width`` x ``height`` pixels
    (:func:`sim_envs.mujoco.scan.scan_views`). Render more views of it with
    :func:`sim_envs.mujoco.scan.render_views` on ``scan.sim`` and ``geom_labels=scan.geom_labels``."""
    from sim_envs.mujoco.scan import scan_views
    from sim_envs.mujoco.scene import build_mujoco
    from sim_envs.scenes.graph import object_aabbs, scene_graph

    if frames < 1 or width < 8 or height < 8:
        raise ValueError(f"scan: expected frames >= 1 and an image of at least 8x8, got {frames} frames of {width}x{height}")
    sim = build_mujoco(scene)
    labels, names = _geom_labels(sim)
    scan = SceneScan(scene, sim, [], names, object_aabbs(sim), scene_graph(sim), labels, scene_label_phrases(scene, names))
    scan.frames = scan_views(sim, frames, width, height, geom_labels=labels)
    return scan


def scan_tabletop(scene_id: str, suite: str, *, frames: int, width: int, height: int) -> SceneScan:
    """:func:`scan_scene` of a shipped tabletop scene; ``ValueError`` naming ``suite`` for a
    scene without a table."""
    scene = load_shipped_scene(scene_id)
    if scene.table is None:
        raise ValueError(f"{suite} suite: expected a tabletop scene, got {scene_id!r}")
    return scan_scene(scene, frames=frames, width=width, height=height)


def fuse_frames(mapper, scan: SceneScan, frames: list[RGBDFrame] | None = None):
    """Reset ``mapper`` and fuse ``frames`` (default: the whole scan); returns the mapper.

    The scan's label names, label phrases and label images (ground truth) reach the mapper only
    when its perception is privileged (``mapper.privileged``: the oracles, ground-truth masks).
    Build the mapper with :func:`agents.builtin.make_mapper`, as the agents do; its featurizer
    loads each encoder once per process."""
    privileged = bool(mapper.privileged)
    if privileged:
        mapper.reset(scan.label_names, scan.label_phrases)
    else:
        mapper.reset()
    for f in scan.frames if frames is None else frames:
        mapper.integrate(f.observation(), segmentation=f.segmentation if privileged else None)
    return mapper


def point_labels(points_n3: np.ndarray, boxes_k23: np.ndarray, *, grow: float = 0.01, base: float = 0.005) -> np.ndarray:
    """Ground-truth object of each map point: the smallest box that contains it, -1 for none.

    Boxes are grown by ``grow`` metres sideways and upwards; their bottom is raised by
    ``base`` metres instead, so the surface an object stands on (table, shelf, the floor of
    its box's footprint) does not count as the object.

    Shape:
        ``points_n3`` (N, 3), ``boxes_k23`` (K, 2, 3) -> (N,) int64.
    """
    pts = np.asarray(points_n3, np.float64).reshape(-1, 3)
    boxes = np.asarray(boxes_k23, np.float64).reshape(-1, 2, 3)
    out = np.full(len(pts), -1, np.int64)
    best = np.full(len(pts), np.inf)
    for k, (lo, hi) in enumerate(boxes):
        lo_g = lo - grow
        lo_g[2] = lo[2] + base
        inside = np.all((pts >= lo_g) & (pts <= hi + grow), axis=1)
        vol = float(np.prod(hi + grow - lo_g))
        take = inside & (vol < best)
        out[take], best[take] = k, vol
    return out
