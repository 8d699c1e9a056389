"""Jobs of the map suites: ``query``, ``ablation`` and ``spatial``, scored against simulator
ground truth (see :mod:`harness.maps.query`, :mod:`harness.maps.ablation`,
:mod:`harness.maps.spatial` for what each measures and how).

One job = one record: ``query`` per (scene, encoder) with ``agent="conceptfusion"``;
``ablation`` per (scene, variant) with ``agent=<variant>``; ``spatial`` per (scene, method)
with ``agent="map-3d"`` or ``"frame-2.5d"``. ``episode_id`` is the scene id. Jobs are
picklable, deterministic and independent: each rebuilds its scene, scan and map.

Options taken from the run's ``agent_kwargs`` (and then part of the job's key):
``frames``, ``width``, ``height`` (scan size) and, for ``ablation``, ``proposer``
(``"rgbd"`` by default; ``"gt"`` for ground-truth masks).
"""

from __future__ import annotations

import difflib
import logging
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["MapJob", "MAP_SUITES", "map_suite_jobs", "run_map_job", "DEFAULT_SCENES", "ablation_encoder"]

_log = logging.getLogger(__name__)

MAP_SUITES = {"query": "map_query", "ablation": "map_ablation", "spatial": "spatial_qa"}
"""Map suite name -> the ``task`` its records carry."""

DEFAULT_SCENES = {"tabletop": 6, "household": 4}
"""How many shipped scenes of each kind a suite uses by default (the first ones, sorted)."""

_OPTIONS = {"query": ("frames", "width", "height"), "ablation": ("frames", "width", "height", "proposer"),
            "spatial": ("frames", "width", "height")}


@dataclass(frozen=True)
class MapJob:
    """One map-suite job: everything a worker needs, picklable."""

    run_id: str
    suite: str
    agent: str
    """The method or variant (``"conceptfusion"``, an ablation variant, ``"map-3d"``, ``"frame-2.5d"``)."""
    encoder: str
    scene_id: str
    seed: int = 0
    options: dict = field(default_factory=dict)
    """Scan size and proposer overrides (stored as the record's ``agent_kwargs``)."""
    out_dir: str | None = None
    """Run folder for side files (the query suite's heatmap .npz); None: none written."""
    note: str = ""
    """Why the encoder differs from the run's, if it does."""

    @property
    def task(self) -> str:
        return MAP_SUITES[self.suite]

    @property
    def episode_id(self) -> str:
        return self.scene_id

    @property
    def label(self) -> str:
        return f"{self.agent} {self.scene_id} [{self.encoder}]"

    def key_record(self) -> dict:
        """The fields :func:`harness.runner.results.record_key` reads, as the job's record will have them."""
        return {"suite": self.suite, "agent": self.agent, "agent_kwargs": dict(self.options), "encoder": self.encoder,
                "episode_id": self.episode_id, "seed": self.seed}


def _scenes(kind: str, limit: int | None) -> list[str]:
    from harness.maps.scan import shipped_scene_ids

    n = DEFAULT_SCENES[kind] if limit is None else int(limit)
    if n < 0:
        raise ValueError(f"limit: expected a non-negative number of scenes, got {limit}")
    return shipped_scene_ids(kind)[:n]


def ablation_encoder(encoder: str) -> tuple[str, str]:
    """The encoder the ablation uses for a run's encoder, and why it differs (empty if not).

    The oracle has no image embeddings to mix, so it falls back to ``"embedded"`` when the
    shipped tower loads, else to ``"color"``.
    """
    if encoder != "oracle":
        return encoder, ""
    from harness.maps.scan import _encoder

    try:
        _encoder("embedded")
        return "embedded", "the oracle has no image tower; the ablation uses 'embedded'"
    except (FileNotFoundError, ImportError, OSError) as exc:
        return "color", f"the oracle has no image tower and 'embedded' is not loadable ({exc}); the ablation uses 'color'"


def map_suite_jobs(name: str, config, run_id: str, *, out_dir: str | Path | None = None) -> list[MapJob]:
    """Jobs of map suite ``name`` for a :class:`harness.runner.run.RunConfig` (``encoder``, ``limit``
    (scenes of each kind), ``seed``, ``agent_kwargs`` (see the module docstring)).

    Raises ``ValueError`` for a suite that is not a map suite, naming the nearest ones.
    """
    if name not in MAP_SUITES:
        near = difflib.get_close_matches(str(name), MAP_SUITES, n=2, cutoff=0.4)
        hint = f"; did you mean {', '.join(repr(n) for n in near)}?" if near else ""
        raise ValueError(f"unknown map suite {name!r}{hint} (map suites: {', '.join(MAP_SUITES)})")
    opts = {k: v for k, v in dict(config.agent_kwargs or {}).items() if k in _OPTIONS[name]}
    base = {"run_id": str(run_id), "suite": name, "seed": int(config.seed), "options": opts,
            "out_dir": None if out_dir is None else str(out_dir)}
    if name == "query":
        return [MapJob(agent="conceptfusion", encoder=config.encoder, scene_id=s, **base) for s in _scenes("tabletop", config.limit)]
    if name == "ablation":
        from harness.maps.ablation import VARIANTS

        enc, note = ablation_encoder(config.encoder)
        return [MapJob(agent=v, encoder=enc, scene_id=s, note=note, **base) for s in _scenes("tabletop", config.limit) for v in VARIANTS]
    from harness.maps.spatial import METHODS

    scenes = _scenes("household", config.limit) + _scenes("tabletop", config.limit)
    return [MapJob(agent=agent, encoder=config.encoder, scene_id=s, **base) for s in scenes for agent in METHODS.values()]


def _run(job: MapJob) -> tuple[dict, dict, dict]:
    o = job.options
    size = {"width": int(o.get("width", 160)), "height": int(o.get("height", 120))}
    if job.suite == "query":
        from harness.maps.query import run_query_scene

        heat = None
        if job.out_dir is not None:
            heat = Path(job.out_dir) / "heatmaps" / f"query-{job.scene_id}-{job.encoder}-seed{job.seed}.npz"
        metrics, extras, timings = run_query_scene(job.scene_id, job.encoder, frames=int(o.get("frames", 12)), seed=job.seed,
                                                   heatmap_path=heat, **size)
        if heat is not None and heat.exists():
            extras["heatmap_npz"] = str(heat.relative_to(job.out_dir))
        return metrics, extras, timings
    if job.suite == "ablation":
        from harness.maps.ablation import run_ablation_scene
        from harness.maps.scan import _encoder

        metrics, extras, timings = run_ablation_scene(job.scene_id, job.agent, _encoder(job.encoder), proposer=str(o.get("proposer", "rgbd")),
                                                      frames=int(o.get("frames", 12)), **size)
        if job.note:
            extras["encoder_note"] = job.note
        return metrics, extras, timings
    from harness.maps.spatial import METHODS, run_spatial_scene

    method = {v: k for k, v in METHODS.items()}[job.agent]
    frames = int(o["frames"]) if "frames" in o else None
    return run_spatial_scene(job.scene_id, method, job.encoder, frames=frames, seed=job.seed, **size)


def run_map_job(job: MapJob) -> list[dict]:
    """Run one job; returns its one record (``status="failed"`` with the error if it raised).

    ``extras["heatmap_npz"]`` (query suite, when the job has an ``out_dir``) is the heatmap's
    path relative to ``out_dir``.
    """
    from harness.runner.results import make_record

    if not isinstance(job, MapJob):
        raise TypeError(f"run_map_job: expected a MapJob, got {type(job).__name__}")
    t0 = time.perf_counter()
    status, error, metrics, extras, timings = "ok", None, {}, {}, {}
    try:
        metrics, extras, timings = _run(job)
    except Exception as exc:  # a broken scene or encoder becomes a failed record, not a stopped run
        _log.warning("map job %s failed: %s", job.label, exc)
        status, error = "failed", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=4)}"
    timings = {**timings, "wall_s": time.perf_counter() - t0}
    return [make_record(
        run_id=job.run_id, suite=job.suite, task=job.task, agent=job.agent, agent_kwargs=dict(job.options), encoder=job.encoder,
        episode_id=job.episode_id, seed=job.seed, status=status, error=error, metrics=metrics, timings=timings,
        category=None, extras=extras,
    )]
