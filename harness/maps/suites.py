"""The map suites: ``query``, ``query-open``, ``ablation`` and ``spatial``, scored against
simulator ground truth (see :mod:`harness.maps.query`, :mod:`harness.maps.query_open`,
:mod:`harness.maps.ablation`, :mod:`harness.maps.spatial` for what each measures and how).
``query``, ``ablation`` and ``spatial`` run on the v1 world's shipped scenes; ``query-v2``,
``ablation-v2`` and ``spatial-v2`` are the same measurements on the v2 world's (object-library
tables and apartments of evaluation seeds, :data:`WORLD_KINDS`); ``query-open`` is v2 only.

A map suite is a :class:`MapSuite`: the ``task`` its records carry, the run options it reads,
the :class:`MapCase` s it scores (``cases``) and how it scores one (``score``). One case = one
record: ``query`` per (scene, encoder) with ``agent="conceptfusion"``, ``query-open`` likewise over the v2 tabletops; ``ablation`` per (scene,
variant) with ``agent=<variant>``; ``spatial`` per (scene, method) with ``agent="map-3d"`` or
``"frame-2.5d"``. Cases are deterministic and independent: each rebuilds its scene, scan and
map. Turning cases into jobs and records is the runner's part (:mod:`harness.runner.map_jobs`).

Options taken from the run's ``agent_kwargs`` (and then part of the job's key):
``frames``, ``width``, ``height`` (scan size: 12 frames of 160x120, ``query-open`` 320x240,
:data:`harness.maps.query_open.SCAN_SIZE`); for ``ablation``, ``proposer``
(``"rgbd"`` by default; ``"gt"`` for ground-truth masks); for ``spatial``, ``parser`` (the
spatial-question parser backend, ``"semantic"`` by default) and ``assume_present`` /
``name_only_fallback`` (both true by default: a question's objects are taken to be there,
:func:`harness.maps.spatial.answer_questions`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from conceptfusion.names import lookup
from conceptfusion.perception.featurizer import is_oracle, make_featurizer
from harness.maps.ablation import VARIANTS, run_ablation_scene
from harness.maps.query import run_query_scene
from harness.maps.query_open import SCAN_SIZE as OPEN_SCAN_SIZE, open_scene_ids, run_open_query_scene
from harness.maps.scan import shipped_scene_ids
from harness.maps.spatial import DEFAULT_PARSER, METHODS, run_spatial_scene
from sim_envs.scenes.splits import splits

__all__ = ["MapCase", "MapSuite", "MAP_SUITES", "get_map_suite", "scene_ids", "DEFAULT_SCENES", "WORLD_KINDS", "ablation_encoder",
           "heatmap_file"]

DEFAULT_SCENES = {"tabletop": 6, "household": 4, "tabletop-v2": 12, "household-v2": 4}
"""How many shipped scenes of each kind a suite uses by default (the first ones, sorted, that the
split file does not reserve). v2 tables vary more (4-12 objects of 91 categories), so the v2
suites take twice as many."""


@dataclass(frozen=True)
class MapCase:
    """One scored unit of a map suite: a method (or variant) on one shipped scene with one encoder."""

    agent: str
    """The method or variant (``"conceptfusion"``, an ablation variant, ``"map-3d"``, ``"frame-2.5d"``)."""
    encoder: str
    scene_id: str
    note: str = ""
    """Why the encoder differs from the run's, if it does."""


@dataclass(frozen=True)
class MapSuite:
    """One map suite."""

    name: str
    task: str
    """The ``task`` its records carry."""
    options: tuple[str, ...]
    """The run's ``agent_kwargs`` it reads (scan size, proposer)."""
    cases: Callable[[str, "int | None"], list[MapCase]]
    """``(run encoder, limit of scenes of each kind) -> cases``, in a fixed order."""
    score: Callable[[MapCase, dict, int, "str | None"], "tuple[dict, dict, dict]"]
    """``(case, options, seed, out_dir) -> (metrics, extras, timings)``; ``out_dir`` (a run
    folder, or None) receives side files. Raises for a broken scene or encoder."""


def scene_ids(kind: str, limit: int | None) -> list[str]:
    """The first ``limit`` shipped scenes of ``kind`` (default :data:`DEFAULT_SCENES`), sorted, that
    are not reserved by the split file (:meth:`sim_envs.scenes.splits.Splits.is_reserved_scene`:
    scenes that calibrated the v1 tower's score floor never enter an evaluation suite)."""
    n = DEFAULT_SCENES[kind] if limit is None else int(limit)
    if n < 0:
        raise ValueError(f"limit: expected a non-negative number of scenes, got {limit}")
    split = splits()
    return [s for s in shipped_scene_ids(kind) if not split.is_reserved_scene(s)][:n]


def ablation_encoder(encoder: str, world: str = "v1") -> tuple[str, str]:
    """The encoder the ablation uses for a run's encoder, and why it differs (empty if not).

    The oracles (``oracle``, ``oracle-open``) have no image embeddings to mix, so they fall
    back to the shipped tower of the ``world`` (``"embedded"`` for v1, ``"embedded-v2"`` for v2)
    when it loads, else to ``"color"``.
    """
    if not is_oracle(encoder):
        return encoder, ""
    tower = "embedded-v2" if world == "v2" else "embedded"
    try:
        make_featurizer(tower)  # loads the tower once per process
        return tower, f"the oracle has no image tower; the ablation uses {tower!r}"
    except (FileNotFoundError, ImportError, OSError) as exc:
        return "color", f"the oracle has no image tower and {tower!r} is not loadable ({exc}); the ablation uses 'color'"


def heatmap_file(out_dir: str | Path, case: MapCase, seed: int) -> Path:
    """Where the query suite writes a case's heatmap ``.npz`` in a run folder."""
    return Path(out_dir) / "heatmaps" / f"query-{case.scene_id}-{case.encoder}-seed{seed}.npz"


def _size(options: dict, default: tuple[int, int] = (160, 120)) -> dict:
    return {"width": int(options.get("width", default[0])), "height": int(options.get("height", default[1]))}


WORLD_KINDS = {"v1": ("tabletop", "household"), "v2": ("tabletop-v2", "household-v2")}
"""Scene kinds (tables, apartments) of each world a map suite runs in."""


def _query_cases(world: str):
    def cases(encoder: str, limit: int | None) -> list[MapCase]:
        return [MapCase("conceptfusion", encoder, s) for s in scene_ids(WORLD_KINDS[world][0], limit)]
    return cases


def _open_cases(encoder: str, limit: int | None) -> list[MapCase]:
    return [MapCase("conceptfusion", encoder, s) for s in open_scene_ids(limit)]


def _ablation_cases(world: str):
    def cases(encoder: str, limit: int | None) -> list[MapCase]:
        enc, note = ablation_encoder(encoder, world)
        return [MapCase(v, enc, s, note) for s in scene_ids(WORLD_KINDS[world][0], limit) for v in VARIANTS]
    return cases


def _spatial_cases(world: str):
    def cases(encoder: str, limit: int | None) -> list[MapCase]:
        tables, rooms = WORLD_KINDS[world]
        scenes = scene_ids(rooms, limit) + scene_ids(tables, limit)
        return [MapCase(agent, encoder, s) for s in scenes for agent in METHODS.values()]
    return cases


def _score_query(case: MapCase, options: dict, seed: int, out_dir: str | None) -> tuple[dict, dict, dict]:
    heat = None if out_dir is None else heatmap_file(out_dir, case, seed)
    metrics, extras, timings = run_query_scene(case.scene_id, case.encoder, frames=int(options.get("frames", 12)), seed=seed,
                                               heatmap_path=heat, **_size(options))
    if heat is not None and heat.exists():
        extras["heatmap_npz"] = str(heat.relative_to(out_dir))
    return metrics, extras, timings


def _score_ablation(case: MapCase, options: dict, seed: int, out_dir: str | None) -> tuple[dict, dict, dict]:
    metrics, extras, timings = run_ablation_scene(case.scene_id, case.agent, case.encoder, proposer=str(options.get("proposer", "rgbd")),
                                                  frames=int(options.get("frames", 12)), **_size(options))
    if case.note:
        extras["encoder_note"] = case.note
    return metrics, extras, timings


def _score_open(case: MapCase, options: dict, seed: int, out_dir: str | None) -> tuple[dict, dict, dict]:
    return run_open_query_scene(case.scene_id, case.encoder, frames=int(options.get("frames", 12)), seed=seed,
                                **_size(options, OPEN_SCAN_SIZE))


_SPATIAL_METHOD = {agent: method for method, agent in METHODS.items()}


def _score_spatial(case: MapCase, options: dict, seed: int, out_dir: str | None) -> tuple[dict, dict, dict]:
    frames = int(options["frames"]) if "frames" in options else None
    return run_spatial_scene(case.scene_id, _SPATIAL_METHOD[case.agent], case.encoder, frames=frames, seed=seed,
                             parser=str(options.get("parser", DEFAULT_PARSER)),
                             **{k: bool(options[k]) for k in ("assume_present", "name_only_fallback") if k in options}, **_size(options))


MAP_SUITES: dict[str, MapSuite] = {
    s.name: s
    for s in (
        MapSuite("query", "map_query", ("frames", "width", "height"), _query_cases("v1"), _score_query),
        MapSuite("query-v2", "map_query", ("frames", "width", "height"), _query_cases("v2"), _score_query),
        MapSuite("query-open", "map_query_open", ("frames", "width", "height"), _open_cases, _score_open),
        MapSuite("ablation", "map_ablation", ("frames", "width", "height", "proposer"), _ablation_cases("v1"), _score_ablation),
        MapSuite("ablation-v2", "map_ablation", ("frames", "width", "height", "proposer"), _ablation_cases("v2"), _score_ablation),
        MapSuite("spatial", "spatial_qa", ("frames", "width", "height", "parser", "assume_present", "name_only_fallback"),
                 _spatial_cases("v1"), _score_spatial),
        MapSuite("spatial-v2", "spatial_qa", ("frames", "width", "height", "parser", "assume_present", "name_only_fallback"),
                 _spatial_cases("v2"), _score_spatial),
    )
}
"""Every map suite by name."""


def get_map_suite(name: str) -> MapSuite:
    """The map suite called ``name``; :class:`~conceptfusion.errors.UnknownNameError` (a
    ``ValueError``) naming the nearest ones otherwise."""
    return lookup(MAP_SUITES, name, "map suite", n=2, listing=f"map suites: {', '.join(MAP_SUITES)}")
