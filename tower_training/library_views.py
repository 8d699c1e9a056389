"""Random table arrangements of object-library instances and labelled views of them (tower v2).

:func:`arrange_table` places 3-8 library instances (``"lib:<id>"`` assets of
:mod:`sim_envs.assets.library`) at random, non-overlapping spots on a plain table and builds a
validated :class:`~sim_envs.scenes.format.Scene`; :func:`random_library_views` renders random
views of such scenes through the one scan function (:func:`sim_envs.mujoco.scan.iter_views`),
with the same random cameras and light changes as the v1 views
(:class:`tower_training.views.ViewConfig`). Each view is labelled with the *instance id* of
every segmentation index, so captions (:mod:`tower_training.captions`) are attached later.

Which instances a scene may hold is the caller's choice (the split's roles): the training
command passes TRAIN instances for ``tower_train`` seeds and VAL instances for ``tower_val``
seeds (:func:`pool_for_seed_role`). A scene follows from its seed and its pool alone.
"""

from __future__ import annotations

import math
from contextlib import closing
from dataclasses import dataclass
from typing import Callable, Iterator, Sequence

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.assets.library import get_instance, instance_size
from sim_envs.mujoco.scan import iter_views
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.format import Scene, SceneObject, Table, scene_from_json
from sim_envs.scenes.splits import Splits
from tower_training.views import ViewConfig, random_poses

__all__ = ["TABLE", "LibraryView", "arrange_table", "labelled_views", "pool_for_seed_role", "random_library_views"]

TABLE = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))
"""The table every arrangement stands on (wood, 1.2 x 0.8 m)."""

_MARGIN_M = 0.02
"""Free space kept between two objects' footprints and between an object and the table edge."""


@dataclass(frozen=True)
class LibraryView:
    """One rendered view of a library arrangement."""

    frame: RGBDFrame
    """The posed frame; ``segmentation`` (H, W) int32 indexes ``object_names`` (-1: table, floor)."""
    scene_seed: int
    """Seed of the arrangement."""
    object_names: tuple[str, ...]
    """Instance id of each object ("mug-003"), by segmentation index."""


def pool_for_seed_role(splits: Splits, seed_role: str) -> list[str]:
    """The instance ids a scene of a seed role may hold.

    ``tower_train``: TRAIN instances; ``tower_val``: VAL instances (held-out instances of train
    categories and every instance of a VAL category); ``calibration``: TRAIN and VAL instances;
    ``evaluation``: TRAIN and TEST instances. TEST instances appear in no role but evaluation.
    """
    roles = {"tower_train": ("train",), "tower_val": ("val",), "calibration": ("train", "val"),
             "evaluation": ("train", "test")}
    if seed_role not in roles:
        raise ValueError(f"seed_role: expected one of {', '.join(roles)}, got {seed_role!r}")
    return sorted(i for r in roles[seed_role] for i in splits.instances_of(r))


def arrange_table(seed: int, pool: Sequence[str], *, n_objects: tuple[int, int] = (3, 8), table: Table = TABLE,
                  max_tries: int = 200) -> Scene:
    """A random table arrangement of ``n_objects`` (inclusive range) distinct instances of ``pool``.

    Each instance keeps its own colour and size; positions and yaws are drawn uniformly and
    rejected while footprints overlap (plus a 2 cm margin) or leave the table. An instance that
    finds no spot in ``max_tries`` draws is replaced by the next one of a random order of
    ``pool``; at most ``3 n`` instances are tried (so a scene may hold fewer than ``n``).

    Args:
        seed: seeds ``np.random.default_rng``; the scene follows from ``seed`` and ``pool``.
        pool: instance ids ("mug-003") to draw from.

    Returns:
        A validated tabletop :class:`Scene` (id ``"libtable-<seed>"``), objects named
        ``"<colour> <category>"`` with their category's synonyms as phrases.
    """
    lo, hi = n_objects
    if not 1 <= lo <= hi:
        raise ValueError(f"n_objects: expected 1 <= lo <= hi, got {n_objects}")
    if len(pool) < lo:
        raise ValueError(f"pool: expected at least {lo} instance ids, got {len(pool)}")
    rng = np.random.default_rng(int(seed))
    n = int(rng.integers(lo, min(hi, len(pool)) + 1))
    ids = [pool[i] for i in rng.permutation(len(pool))[: 3 * n]]  # spares for objects that do not fit
    (cx, cy, _), (sx, sy, _) = table.center, table.size
    placed: list[tuple[np.ndarray, np.ndarray]] = []
    objects = []
    for iid in ids:
        if len(objects) == n:
            break
        inst = get_instance(iid)
        size = instance_size(iid)
        for _ in range(max_tries):
            yaw = float(rng.uniform(-math.pi, math.pi))
            c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
            half = np.array([c * size[0] + s * size[1], s * size[0] + c * size[1]]) / 2 + _MARGIN_M / 2
            room = np.array([sx / 2, sy / 2]) - half - _MARGIN_M / 2
            if np.any(room <= 0):
                break
            xy = np.array([cx, cy]) + rng.uniform(-room, room)
            if all(np.any(np.minimum(xy + half, h) - np.maximum(xy - half, l) <= 0) for l, h in placed):
                placed.append((xy - half, xy + half))
                objects.append(SceneObject(f"obj{len(objects)}", f"{inst.color} {inst.category}", inst.category,
                                           inst.asset, inst.color, (float(xy[0]), float(xy[1]), table.top_z), yaw,
                                           tuple(float(v) for v in size)))
                break
    if not objects:
        raise ValueError(f"arrange_table(seed={seed}): no instance of the draw fits on the table")
    scene = Scene(f"libtable-{int(seed)}", "tabletop", int(seed), table, tuple(objects))
    return scene_from_json(scene.to_json(), source=f"libtable-{int(seed)}")


def labelled_views(
    seeds: Sequence[int], make_scene: Callable[[int], Scene], make_poses: Callable, views_per_scene: int,
    rng: np.random.Generator, config,
) -> Iterator[LibraryView]:
    """Render ``views_per_scene`` views of ``make_scene(seed)`` for each seed, labelled with
    instance ids: the one loop behind the table and apartment views.

    One MuJoCo model and one camera per scene, released before the next. ``make_poses(scene, ms,
    views_per_scene, rng, config)`` yields the (eye, target) pairs lazily, so each view's
    randomness is drawn from ``rng`` when the view is asked for; ``config`` has ``width``,
    ``height`` and ``fovy_deg``.
    """
    if views_per_scene < 1:
        raise ValueError(f"views_per_scene: expected at least 1, got {views_per_scene}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy Generator, got {type(rng).__name__}")
    for seed in seeds:
        scene = make_scene(int(seed))
        ms = build_mujoco(scene)
        names = tuple(o.asset.split(":", 1)[1] for o in scene.objects)
        poses = make_poses(scene, ms, views_per_scene, rng, config)
        with closing(iter_views(ms, poses, config.width, config.height, fovy_deg=config.fovy_deg)) as frames:
            for f in frames:
                yield LibraryView(frame=f, scene_seed=int(seed), object_names=names)


def random_library_views(
    seeds: Sequence[int], pool: Sequence[str], views_per_scene: int, rng: np.random.Generator,
    config: ViewConfig = ViewConfig(),
) -> Iterator[LibraryView]:
    """Render ``views_per_scene`` random views of ``arrange_table(seed, pool)`` for each seed.

    Cameras and lights as :func:`tower_training.views.random_tabletop_views`; each view's
    randomness is drawn from ``rng`` when the view is asked for.
    """
    return labelled_views(seeds, lambda seed: arrange_table(seed, pool), random_poses, views_per_scene, rng, config)
