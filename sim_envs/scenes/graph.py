"""Ground-truth scene graph from the simulation state: boxes, support, containment.

For scoring only: agents never receive it unless they are declared privileged.
"""

from __future__ import annotations

import numpy as np

__all__ = ["object_aabbs", "furniture_aabbs", "scene_graph"]

_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64)


def object_aabbs(sim) -> np.ndarray:
    """World axis-aligned box of every scene object in the current state: from its geoms' boxes
    for a :class:`~sim_envs.mujoco.scene.MujocoScene`; a simulation that computes its own (a
    :class:`~sim_envs.pybullet.scene.PyBulletScene`: the size box in the object's pose) is asked.

    Shape:
        returns (num_objects, 2, 3): ``[i, 0]`` lower corner, ``[i, 1]`` upper corner.
    """
    if hasattr(sim, "object_aabbs"):
        return sim.object_aabbs()
    return _group_aabbs(sim, sim.geom_object, len(sim.scene.objects))


def furniture_aabbs(sim) -> np.ndarray:
    """World axis-aligned box of every piece of furniture (household scenes), as
    :func:`object_aabbs`.

    Shape:
        returns (num_furniture, 2, 3): ``[j, 0]`` lower corner, ``[j, 1]`` upper corner.
    """
    if hasattr(sim, "furniture_aabbs"):
        return sim.furniture_aabbs()
    return _group_aabbs(sim, sim.geom_furniture, len(sim.scene.furniture))


def _group_aabbs(sim, geom_group: np.ndarray, n: int) -> np.ndarray:
    model, data = sim.model, sim.data
    signs = _SIGNS
    out = np.empty((n, 2, 3))
    for i in range(n):
        geoms = np.flatnonzero(geom_group == i)
        corners = []
        for g in geoms:
            centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
            local = centre + signs * half
            corners.append(local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g])
        pts = np.concatenate(corners)
        out[i, 0], out[i, 1] = pts.min(axis=0), pts.max(axis=0)
    return out


def scene_graph(sim, *, contact_tol: float = 0.01, inside_tol: float = 0.01) -> dict:
    """Objects with boxes, and the relations between them.

    * ``supported_by``: A rests on B when A's bottom is within ``contact_tol`` of B's top and
      their footprints overlap (the table counts as ``"table"``);
    * ``inside``: A is inside B when A's box lies within B's box grown by ``inside_tol`` (B's
      top open: A may stick out above).
    """
    boxes = object_aabbs(sim)
    scene = sim.scene
    table_top = scene.table.top_z if scene.table is not None else None
    objects, support, inside = [], [], []
    for i, o in enumerate(scene.objects):
        lo, hi = boxes[i]
        objects.append({"id": o.id, "name": o.name, "category": o.category, "aabb": [lo.tolist(), hi.tolist()]})
        if table_top is not None and abs(lo[2] - table_top) <= contact_tol:
            support.append((o.id, "table"))
        for j, p in enumerate(scene.objects):
            if i == j:
                continue
            plo, phi = boxes[j]
            overlap = np.all(np.minimum(hi[:2], phi[:2]) > np.maximum(lo[:2], plo[:2]))
            if overlap and abs(lo[2] - phi[2]) <= contact_tol:
                support.append((o.id, p.id))
            if np.all(lo[:2] >= plo[:2] - inside_tol) and np.all(hi[:2] <= phi[:2] + inside_tol) and lo[2] >= plo[2] - inside_tol and (hi[:2] - lo[:2] < phi[:2] - plo[:2]).all():
                inside.append((o.id, p.id))
    graph = {"objects": objects, "supported_by": support, "inside": inside}
    if scene.is_household:
        _household_relations(sim, boxes, graph, contact_tol)
    return graph


def _household_relations(sim, boxes: np.ndarray, graph: dict, contact_tol: float) -> None:
    """Add rooms, furniture boxes, each object's room, and support / containment by furniture
    surfaces and the floor (computed from the current state, not from the scene file)."""
    from sim_envs.assets.furniture import FURNITURE

    scene = sim.scene
    fboxes = furniture_aabbs(sim)
    graph["rooms"] = [{"id": r.id, "name": r.name, "floor": [list(r.floor[0]), list(r.floor[1])]} for r in scene.rooms]
    graph["furniture"] = []
    for j, f in enumerate(scene.furniture):
        room = scene.room_at(f.position[:2])
        graph["furniture"].append(
            {"id": f.id, "name": f.name, "category": f.category, "room": room.id if room else None, "aabb": [fboxes[j, 0].tolist(), fboxes[j, 1].tolist()]}
        )
    on_object = {a for a, _ in graph["supported_by"]}
    index = {o.id: i for i, o in enumerate(scene.objects)}
    in_object = {a: b for a, b in graph["inside"]}
    for i, o in enumerate(scene.objects):
        lo, hi = boxes[i]
        centre = (lo[:2] + hi[:2]) / 2
        room = scene.room_at(centre)
        graph["objects"][i]["room"] = room.id if room else None
        if o.id in on_object:
            continue
        container = in_object.get(o.id)
        if container is not None and lo[2] - boxes[index[container], 0, 2] <= 0.03:  # resting on a container's inner floor
            graph["supported_by"].append((o.id, container))
            continue
        found = False
        for f in scene.furniture:
            local = f.to_local(centre)
            for srf in f.surfaces():
                if srf.contains(local) and abs(lo[2] - (f.position[2] + srf.z)) <= contact_tol:
                    graph["supported_by"].append((o.id, f.id))
                    if srf.kind == "inside" and FURNITURE[f.category].container:
                        graph["inside"].append((o.id, f.id))
                    found = True
                    break
            if found:
                break
        if not found and abs(lo[2]) <= contact_tol and room is not None:
            graph["supported_by"].append((o.id, "floor"))
