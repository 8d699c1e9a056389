"""The evaluation suites: which episodes, which agents, which settings.

Episode suites roll agents through environment episodes (:mod:`harness.runner.tasks`):

* ``rearrange``: the shipped tabletop episodes (``scenes/tabletop/episodes-v1.jsonl``), the
  paper's "push X to the left/right of the line";
* ``rearrange-v2``: rearrangement on the v2 tabletops filled from the object library
  (``scenes/tabletop-v2/episodes-v2.jsonl``, evaluation seeds; goals named by name, synonym,
  attribute or function; not a default suite);
* ``search``: the shipped household object-search episodes (``scenes/household/episodes-v1.jsonl``);
* ``search-v2``: object search in the v2 apartments filled from the object library
  (``scenes/household-v2/episodes-v2.jsonl``; not a default suite).

Map suites score ConceptFusion maps against simulator ground truth (:mod:`harness.maps.suites`):

* ``query``: text, image and click queries over fused tabletop maps (paper Tables I-III);
* ``ablation``: global-only / local-only / no-uniqueness / full pixel features (paper's ablation);
* ``spatial``: distance, relative position, support and containment questions from the
  ground-truth scene graph, answered from the 3D map and from a single RGB-D frame (2.5D).

``regression`` is a small pinned episode suite with per-agent success floors, run in CI.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from conceptfusion.names import lookup
from sim_envs.scenes.episodes import SCENES_ROOT

__all__ = ["Suite", "SUITES", "get_suite", "DEFAULT_SUITES"]


@dataclass(frozen=True)
class Suite:
    """One suite."""

    name: str
    kind: str
    """``"episodes"`` (agents in environments) or ``"maps"`` (map quality against ground truth)."""
    description: str
    task: str | None = None
    episodes_file: Path | None = None
    agents: tuple[str, ...] = ()
    """Agents run by default (map-equipped first, then the map-free baselines)."""
    env_kwargs: dict = field(default_factory=dict)
    timeout_s: float = 600.0
    """Per-episode limit; past it the episode is recorded as ``timeout``."""
    limit: int | None = None
    """Use only the first ``limit`` episodes (None: all)."""
    floors: dict = field(default_factory=dict)
    """Agent -> minimum success rate (regression suites)."""
    encoder: str | None = None
    """Perception pinned by the suite (None: the run's ``--encoder``). The regression suites pin
    the privileged ``oracle`` so that their floors guard planning and control; perception has its
    own checks (the map suites)."""


SUITES: dict[str, Suite] = {
    s.name: s
    for s in (
        Suite(
            "rearrange", "episodes", "tabletop rearrangement: push named objects across the line (MuJoCo)",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop" / "episodes-v1.jsonl",
            agents=("map-pusher", "frame-pusher", "random-pusher"),
            env_kwargs={"width": 160, "height": 120, "scan_frames": 8},
        ),
        Suite(
            "rearrange-v2", "episodes",
            "tabletop rearrangement on library tabletops (evaluation seeds): goals named by name, synonym, attribute or function",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop-v2" / "episodes-v2.jsonl",
            agents=("map-pusher", "frame-pusher", "random-pusher"),
            env_kwargs={"width": 160, "height": 120, "scan_frames": 8},
        ),
        Suite(
            "search", "episodes", "object search in apartments: stop within 1 m of the described object",
            task="object_search", episodes_file=SCENES_ROOT / "household" / "episodes-v1.jsonl",
            agents=("map-navigator", "frame-searcher", "random-walker"),
            env_kwargs={"width": 160, "height": 120},
        ),
        Suite(
            "search-v2", "episodes",
            "object search in library-filled apartments (evaluation seeds): goals named by name, synonym, attribute or function",
            task="object_search", episodes_file=SCENES_ROOT / "household-v2" / "episodes-v2.jsonl",
            agents=("map-navigator", "frame-searcher", "random-walker"),
            env_kwargs={"width": 160, "height": 120},
        ),
        Suite("query", "maps", "text, image and click query localisation over fused tabletop maps (3D mIoU, detection accuracy)"),
        Suite("ablation", "maps", "pixel-feature ablation: global only, local only, no uniqueness, full (mAcc, f-mIoU)"),
        Suite("spatial", "maps", "spatial questions from the scene graph: 3D map vs single RGB-D frame"),
        Suite(
            "regression-rearrange", "episodes", "pinned tabletop episodes with success floors, oracle perception (CI)",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop" / "episodes-v1.jsonl",
            agents=("map-pusher", "frame-pusher", "random-pusher"), env_kwargs={"width": 128, "height": 96, "scan_frames": 6},
            limit=6, floors={"map-pusher": 0.66, "frame-pusher": 0.33, "random-pusher": 0.0}, encoder="oracle",
        ),
        Suite(
            "regression-search", "episodes", "pinned household search episodes with success floors, oracle perception (CI)",
            task="object_search", episodes_file=SCENES_ROOT / "household" / "episodes-v1.jsonl",
            agents=("map-navigator", "frame-searcher", "random-walker"), env_kwargs={"width": 160, "height": 120},
            limit=4, floors={"map-navigator": 0.75, "frame-searcher": 0.0, "random-walker": 0.0}, encoder="oracle",
        ),
    )
}
"""Every suite by name."""

DEFAULT_SUITES = ("query", "ablation", "spatial", "rearrange", "search")
"""What ``cfharness run`` runs with no ``--suite``."""


def get_suite(name: str) -> Suite:
    """The suite called ``name``; ``ValueError`` naming the nearest ones otherwise."""
    return lookup(SUITES, name, "suite")
