"""Seeded procedural scene generation (tabletop scenes)."""

from __future__ import annotations

import numpy as np

from sim_envs.assets.objects import ASSETS, COLORS
from sim_envs.scenes.format import Scene, SceneObject, Table

__all__ = ["generate_tabletop"]


def generate_tabletop(seed: int, *, num_targets: tuple[int, int] = (3, 8), num_distractors: tuple[int, int] = (1, 3)) -> Scene:
    """A table with 3-8 target objects plus distractors and a left/right dividing line.

    Objects get distinct (colour, kind) names ("red mug", "blue can"), random yaw and a
    placement that keeps footprints 3 cm apart and 5 cm from the table edge. The dividing
    line runs along the table's y axis through x = 0.

    Randomness: everything follows from ``seed`` (``np.random.default_rng(seed)``).
    """
    rng = np.random.default_rng(seed)
    table = Table(center=(0.0, 0.0, 0.375), size=(1.2, 0.8, 0.05), material="wood")
    n = int(rng.integers(num_targets[0], num_targets[1] + 1)) + int(rng.integers(num_distractors[0], num_distractors[1] + 1))
    kinds = sorted(ASSETS)
    colors = sorted(COLORS)
    names: set[str] = set()
    placed: list[SceneObject] = []
    attempts = 0
    while len(placed) < n and attempts < 2000:
        attempts += 1
        kind = kinds[int(rng.integers(len(kinds)))]
        color = colors[int(rng.integers(len(colors)))]
        name = f"{color} {ASSETS[kind].category}"
        if name in names:
            continue
        size = tuple(float(s) * float(rng.uniform(0.9, 1.15)) for s in ASSETS[kind].default_size)
        yaw = float(rng.uniform(-np.pi, np.pi))
        margin = 0.05 + max(size[:2]) / 2
        x = float(rng.uniform(-table.size[0] / 2 + margin, table.size[0] / 2 - margin))
        y = float(rng.uniform(-table.size[1] / 2 + margin, table.size[1] / 2 - margin))
        obj = SceneObject(
            id=f"obj{len(placed)}", name=name, category=ASSETS[kind].category, asset=kind, color=color,
            position=(x, y, table.top_z), yaw=yaw, size=size,
            phrases=(f"a {color} {ASSETS[kind].category}",) + ASSETS[kind].phrases,
        )
        lo, hi = obj.footprint()
        if any(np.all(np.minimum(hi, h2) - np.maximum(lo, l2) > -0.03) for l2, h2 in (p.footprint() for p in placed)):
            continue
        if abs(x) < max(size[:2]) / 2 + 0.02:  # keep objects off the line itself
            continue
        placed.append(obj)
        names.add(name)
    return Scene(
        id=f"tabletop-{seed:04d}", kind="tabletop", seed=int(seed), table=table, objects=tuple(placed),
        line=((0.0, -table.size[1] / 2), (0.0, table.size[1] / 2)),
    )
