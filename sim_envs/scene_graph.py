"""Ground-truth scene graph from the simulation state: boxes, support, containment.

For scoring only: agents never receive it unless they are declared privileged.
"""

from __future__ import annotations

import numpy as np

__all__ = ["object_aabbs", "scene_graph"]


def object_aabbs(sim) -> np.ndarray:
    """World axis-aligned box of every scene object, from its geoms' boxes in the current state.

    Shape:
        returns (num_objects, 2, 3): ``[i, 0]`` lower corner, ``[i, 1]`` upper corner.
    """
    model, data = sim.model, sim.data
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64)
    out = np.empty((len(sim.scene.objects), 2, 3))
    for i in range(len(sim.scene.objects)):
        geoms = np.flatnonzero(sim.geom_object == i)
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
    return {"objects": objects, "supported_by": support, "inside": inside}
