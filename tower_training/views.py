"""Random views of procedural tabletop scenes, for training and testing image encoders.

Each scene (:func:`~sim_envs.scenes.gen_tabletop.generate_tabletop`) is rendered from random
viewpoints: azimuth uniform on the circle, distance from the table centre and camera height
above the table top drawn from ranges, the look-at point jittered over the table top. The
two scene lights get a random common brightness per view (``model.light_diffuse`` scaled,
never tinted: colour words must stay true). Every view carries its instance segmentation
and the names of the objects it indexes, so crops can be labelled without any mapping code.

Randomness: a ``np.random.Generator`` passed in; the scenes follow from their seeds.
"""

from __future__ import annotations

import math
from contextlib import closing
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.mujoco.scan import iter_views
from sim_envs.mujoco.scene import build_mujoco
from sim_envs.scenes.gen_tabletop import generate_tabletop

__all__ = ["ViewConfig", "check_view_config", "TabletopView", "random_poses", "random_tabletop_views"]


def check_view_config(config, ranges: Sequence[str]) -> None:
    """``ValueError`` unless ``config.width`` and ``config.height`` are at least 16 pixels and each
    field named in ``ranges`` is a range ``0 < lo <= hi``."""
    if config.width < 16 or config.height < 16:
        raise ValueError(f"width, height: expected at least 16 pixels, got {config.width}x{config.height}")
    for name in ranges:
        lo, hi = getattr(config, name)
        if not 0 < lo <= hi:
            raise ValueError(f"{name}: expected a range 0 < lo <= hi, got {(lo, hi)}")


@dataclass(frozen=True)
class ViewConfig:
    """Where the random cameras go and how they render."""

    width: int = 320
    """Image width in pixels."""
    height: int = 240
    """Image height in pixels."""
    fovy_deg: float = 60.0
    """Vertical field of view."""
    distance_m: tuple[float, float] = (0.55, 1.4)
    """Horizontal distance of the camera from the table centre (range)."""
    height_m: tuple[float, float] = (0.25, 0.95)
    """Camera height above the table top (range)."""
    target_jitter_m: float = 0.25
    """Look-at point: table centre plus a uniform offset of at most this in x and y."""
    light_gain: tuple[float, float] = (0.6, 1.25)
    """Common factor on the lights' diffuse colour, per view (range)."""

    def __post_init__(self) -> None:
        check_view_config(self, ("distance_m", "height_m", "light_gain"))


@dataclass(frozen=True)
class TabletopView:
    """One rendered view of a generated tabletop scene, with the names its labels index."""

    frame: RGBDFrame
    """The posed frame; its ``segmentation`` (H, W) int32 indexes ``object_names`` (-1: table,
    floor, line)."""
    scene_seed: int
    """Seed of the generated scene."""
    object_names: tuple[str, ...]
    """Name of each object ("red mug"), by segmentation index."""


def random_poses(scene, ms, views_per_scene: int, rng: np.random.Generator, config: ViewConfig) -> Iterator[tuple]:
    """Random (eye, target) pairs around the table; before yielding each, set the lights' random
    brightness for that view (the randomness is drawn view by view, when the view is rendered)."""
    base_light = ms.model.light_diffuse.copy()
    cx, cy, _ = scene.table.center
    top = scene.table.top_z
    for _ in range(views_per_scene):
        az = rng.uniform(-math.pi, math.pi)
        dist = rng.uniform(*config.distance_m)
        eye = (cx + dist * math.cos(az), cy + dist * math.sin(az), top + rng.uniform(*config.height_m))
        j = config.target_jitter_m
        target = (cx + rng.uniform(-j, j), cy + rng.uniform(-j, j), top)
        ms.model.light_diffuse[:] = base_light * rng.uniform(*config.light_gain)
        yield eye, target


def random_tabletop_views(
    seeds: Sequence[int], views_per_scene: int, rng: np.random.Generator, config: ViewConfig = ViewConfig()
) -> Iterator[TabletopView]:
    """Render ``views_per_scene`` random views of each scene ``generate_tabletop(seed)``.

    One MuJoCo model and one camera per scene (:func:`sim_envs.mujoco.scan.iter_views`),
    released before the next scene. Each view's randomness is drawn from ``rng`` when that view
    is asked for, so a consumer that draws from the same ``rng`` between views interleaves with it.
    """
    if views_per_scene < 1:
        raise ValueError(f"views_per_scene: expected at least 1, got {views_per_scene}")
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy Generator, got {type(rng).__name__}")
    for seed in seeds:
        scene = generate_tabletop(int(seed))
        ms = build_mujoco(scene)
        names = tuple(o.name for o in scene.objects)
        poses = random_poses(scene, ms, views_per_scene, rng, config)
        with closing(iter_views(ms, poses, config.width, config.height, fovy_deg=config.fovy_deg)) as frames:
            for f in frames:
                yield TabletopView(frame=f, scene_seed=int(seed), object_names=names)
