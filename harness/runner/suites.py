"""The evaluation suites: which episodes, which agents, which settings.

Episode suites roll agents through environment episodes (:mod:`harness.runner.tasks`):

* ``rearrange``: the shipped tabletop episodes (``scenes/tabletop/episodes-v1.jsonl``), the
  paper's "push X to the left/right of the line";
* ``rearrange-v2``: rearrangement on the v2 tabletops filled from the object library, on the
  sealed test set (``scenes/sealed-v2/rearrange-episodes-v2.jsonl``, 160 episodes; goals named by
  name, synonym, attribute or function);
* ``search``: the shipped household object-search episodes (``scenes/household/episodes-v1.jsonl``);
* ``search-v2``: object search in the v2 apartments filled from the object library, on the sealed
  test set (``scenes/sealed-v2/search-episodes-v2.jsonl``, 150 episodes);
* ``chain-v2``: multi-goal search in the same apartments (``scenes/sealed-v2/chain-episodes-v2.jsonl``,
  30 chains of 2, 3 and 4 goals revealed one at a time; success per position in the chain:
  ``reached_k``, the first k goals reached in a row);
* ``fetch-v2``: "explore, then fetch" in the other sealed apartments
  (``scenes/sealed-v2/fetch-episodes-v2.jsonl``, 30 episodes: 200 steps of exploration, then 2-4
  goals one at a time with 150 steps each; not a default suite).

The v2 suites' agents come in matched pairs: each map-equipped agent beside its map-free twin
(``twin-pusher``, ``twin-navigator``: the same views, exploration, planner and rules, no concept
vectors fused across views), then the weak reactive baselines and the random references. Their
episodes are the sealed test set (:mod:`sim_envs.scenes.sealed`): checked against its manifest
before any episode runs; the first evaluation episodes (``scenes/tabletop-v2/``,
``scenes/household-v2/``) are a development set now (:mod:`harness.runner.develop`, ``dev2``).

Map suites score ConceptFusion maps against simulator ground truth (:mod:`harness.maps.suites`):

* ``query``: text, image and click queries over fused tabletop maps (paper Tables I-III);
* ``query-open``: open-vocabulary text queries over fused v2 tabletop maps (the paper's UnCoCo
  analogue): names, synonyms, parents, attributes, functions and absent objects, split by seen
  instance, held-out instance and held-out category;
* ``ablation``: global-only / local-only / no-uniqueness / full pixel features (paper's ablation);
* ``spatial``: questions for the eight spatial comparators from the ground-truth scene graph in
  many phrasings, read by the spatial-question parser and answered from the 3D map and from a
  single RGB-D frame (2.5D).

The regression suites (``regression-rearrange`` and ``regression-search`` with the privileged
oracle perception pinned, ``regression-rearrange-embedded`` with the shipped embedded tower) pin
the first episodes of the shipped files and hold every built-in agent to a lower bound on its success rate
(the random agents to an upper bound), run in CI. ``regression-rearrange-v2`` and ``regression-search-v2``
gate the headline pipeline the same way: the v2 world, ``embedded-v2`` pinned, the agents' shipped
settings (``identify``, ``presume_after``, the search proposals) and the v2 camera sizes, on the
gate's own episodes (``scenes/gate-v2/``, :data:`GATE_FOLDER`); every agent whose success can fall
is bounded, the map agents' twins included (``frame-searcher``, which solves next to nothing with
embedded perception, cannot get a bound that fails and is left out). ``regression-search-v2-pybullet``
is the gate's PyBullet slice: the same pinned and calibration searches run in PyBullet with the
privileged ``oracle-open`` perception pinned. It gates the simulator (geometry, physics, depth,
segmentation, the agents' control); oracle-open perception takes the MuJoCo-trained tower's domain
gap out of it (that gap is measured by the sim-to-sim table, ``search-v2`` against
``search-v2-pybullet``), and the embedded tower in PyBullet would cost 30-65 s an episode. It runs
``map-navigator`` alone, the agent that uses all of it (PyBullet's depth and segmentation fused
into its map, its planner and controller on PyBullet's physics): every bound is set at the gate's
family-wise level (:mod:`harness.runner.bounds`), and a second bound would lower two pushers'
lower bounds by one success each, ``map-pusher``'s in ``regression-rearrange-v2`` to 33 of 47,
which the backwards-``identify`` sabotage reaches; ``twin-navigator`` (also about 27 s an
episode in PyBullet), ``oracle-searcher`` and ``random-walker`` are left out (the MuJoCo gate
bounds them). The bounds and each agent's episode count are
not set here: they are derived by :mod:`harness.runner.bounds` from recorded calibration runs over
other episodes of the same generators (``calibration_file``) and read from :data:`BOUNDS_FILE`.

Every episode suite runs :func:`suite_episodes`: the episodes of its file (a sealed file verified
against its manifest first) minus those on scenes the split file reserves (:mod:`sim_envs.scenes.splits`: the shipped scenes that chose or measured the
v1 tower's score floor); ``limit`` and the per-agent counts take the first episodes of what is left.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

from conceptfusion.errors import HarnessError
from conceptfusion.io_utils import read_json_file
from conceptfusion.names import lookup
from sim_envs.scenes.episodes import SCENES_ROOT, Episode, load_episodes
from sim_envs.scenes.chain_episodes import check_chains_reachable
from sim_envs.scenes.sealed import SEALED_FOLDER, is_sealed_file, verify_sealed
from sim_envs.scenes.splits import splits

__all__ = ["Suite", "SUITES", "get_suite", "DEFAULT_SUITES", "REARRANGE_V2_ENV", "REARRANGE_V2_LIMIT", "SEARCH_V2_LIMIT", "CHAIN_V2_LIMIT",
           "FRAME_SEARCHER_LIMIT", "GATE_FOLDER", "HEADLINE_GATE", "suite_encoder", "suite_episodes", "BOUNDS_FILE",
           "calibrated_bounds", "suite_over", "EPISODES_PREFIX", "TASK_TEMPLATES", "episodes_suite", "episodes_suite_name"]

BOUNDS_FILE = Path(__file__).resolve().parents[1] / "data" / "bounds" / "bounds.json"
"""The regression suites' success bounds and episode counts, written by
``cfharness develop bounds --calibrate`` (never by hand)."""


def calibrated_bounds(name: str, path: Path = BOUNDS_FILE) -> dict:
    """``lower_bounds``, ``upper_bounds``, ``agent_limits`` and ``limit`` of regression suite
    ``name`` as :data:`BOUNDS_FILE` records them (Suite keyword arguments); empty when the file or
    the suite is missing there (the suite is then not calibrated, which the bound check refuses).

    Raises:
        HarnessError: the file is not valid bounds JSON.
    """
    if not path.is_file():
        return {}
    try:
        agents = read_json_file(path, "bounds file", HarnessError)["suites"].get(name, {}).get("agents", {})
        lower = {a: float(b["value"]) for a, b in agents.items() if b["bound"] == "lower"}
        upper = {a: float(b["value"]) for a, b in agents.items() if b["bound"] == "upper"}
        limits = {a: int(b["episodes"]) for a, b in agents.items()}
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise HarnessError(f"{path}: not a bounds file written by cfharness develop bounds --calibrate "
                           f"({type(exc).__name__}: {exc}); regenerate it") from exc
    if not agents:
        return {}
    return {"lower_bounds": lower, "upper_bounds": upper, "agent_limits": limits, "limit": max(limits.values())}


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
    """Use only the first ``limit`` episodes of :func:`suite_episodes` (None: all)."""
    lower_bounds: dict = field(default_factory=dict)
    """Agent -> minimum success rate (regression suites; from :data:`BOUNDS_FILE`)."""
    upper_bounds: dict = field(default_factory=dict)
    """Agent -> maximum success rate (regression suites, random agents: a broken success
    function shows as a random agent succeeding; from :data:`BOUNDS_FILE`)."""
    agent_limits: dict = field(default_factory=dict)
    """Agent -> how many of the first episodes it runs, instead of ``limit`` (regression suites:
    each agent's count from the power computation of :mod:`harness.runner.bounds`)."""
    calibration_file: Path | None = None
    """Episodes the suite's bounds are calibrated on (regression suites): same generators and
    settings, none of the suite's own episodes."""
    encoder: str | None = None
    """Perception pinned by the suite (None: the run's ``--encoder``). The regression suites pin
    the privileged ``oracle`` so that their bounds guard planning and control; perception has its
    own checks (the map suites)."""
    default_encoder: str = "embedded"
    """Perception when the run names none: the shipped tower trained for the suite's world
    (``embedded`` for the v1 world, ``embedded-v2`` for the object library's)."""
    scenes_root: Path | None = None
    """Folder the episodes' scene references resolve under (None: the shipped ``scenes/``); a
    user's episode suite (:func:`episodes_suite`) may name its own."""
    question: str = ""
    """The question the suite answers, in plain words: the title of its card on the report's first
    screen (:mod:`harness.report.cards`; empty: a generic question)."""
    headline_metric: str = ""
    """The metric the card ranks agents by and compares (higher is better; empty: ``success`` when
    the records have it, else their first metric)."""
    baseline: str = ""
    """The agent the card compares the best agent with when no matched twin (``extras.twin_of``)
    ran (empty: none; the card then shows the best figure with its interval)."""
    verdicts: tuple[str, str] = ("map helps", "map hurts")
    """The card's verdict when the difference's 95% interval lies above 0, and when it lies below
    ("no detectable difference" when it holds 0)."""


REARRANGE_V2_ENV = {"width": 320, "height": 240, "scan_frames": 8}
"""Environment of ``rearrange-v2``: 320x240 frames (the size the v2 tower was trained at and
``query-open`` scans at) and an 8-frame orbit scan, chosen on development episodes
(:mod:`harness.runner.develop`) for the open-world tables; see docs/measurement-history.md."""

SEARCH_V2_ENV = {"width": 320, "height": 240}
"""Environment of ``search-v2``: 320x240 frames. The search agents' proposals
(:data:`~conceptfusion.perception.featurizer.SEARCH_PROPOSER`) keep regions down to 19 pixels at
this size, so objects a base sees a few pixels wide at 160x120 are segmented on their own, and
their score floor is derived for these views (``score_floor_search``). Chosen on development
episodes (:mod:`harness.runner.develop`); see docs/measurement-history.md."""

REARRANGE_V2_LIMIT = 64
"""Episodes ``rearrange-v2`` runs unless ``--limit`` says otherwise: the first 64 of its 160, so
that the default comparison fits its time; ``--limit 160`` runs them all (the headline figures)."""

INSTRUCT_FOLDER = SCENES_ROOT / "instruct-v2"
"""The instruction apartments and episodes (``python -m scenes.make_instruct_v2``)."""
INSTRUCT_V2_ENV = {**SEARCH_V2_ENV, "room_plan": True}
"""Environment of ``instruct-v2``: ``search-v2``'s, plus the labelled room plan every agent is told."""
INSTRUCT_V2_LIMIT = 24
"""Episodes ``instruct-v2`` runs unless ``--limit`` says otherwise (``--limit 160``: all)."""

SEARCH_V2_LIMIT = 16
"""Episodes ``search-v2`` runs unless ``--limit`` says otherwise: the first 16 of its 150 (goals
named by name, synonym, attribute, function in turn), so that the default comparison fits its
time; ``--limit 150`` runs them all (the headline figures)."""

CHAIN_V2_LIMIT = 3
"""Chains ``chain-v2`` runs unless ``--limit`` says otherwise: the first 3 of its 30 (one each of
2, 3 and 4 goals); ``--limit 30`` runs them all (the headline figures)."""

GATE_FOLDER = SCENES_ROOT / "gate-v2"
"""Episodes of the v2 regression suites, pinned and calibration (``python -m scenes.make_gate_v2``):
calibration seeds, TRAIN and VAL instances only, none in any other file."""

FRAME_SEARCHER_LIMIT = 8
"""Episodes the weak reactive ``frame-searcher`` runs in ``search-v2`` unless ``--limit`` says
otherwise: the slowest agent (it segments every frame) and a reference, not the headline
comparison (which is the map navigator against its twin)."""

_Q_PUSH = "Does the map help the pusher find and push the described object?"
_Q_SEARCH = "Does the map help the navigator reach the described object?"
_Q_QUERY = "How well does the map find objects named, described, shown or clicked?"
_Q_QUERY_OPEN = "How well does the map find objects named in words of every kind, seen and held out?"
_ABLATION_CARD = {"question": "Which part of the pixel-aligned features matters?", "headline_metric": "macc",
                  "baseline": "global", "verdicts": ("beats global only", "worse than global only")}
_SPATIAL_CARD = {"question": "Does a 3D map answer spatial questions better than a single frame?", "headline_metric": "accuracy",
                 "baseline": "frame-2.5d"}

SUITES: dict[str, Suite] = {
    s.name: s
    for s in (
        Suite(
            "rearrange", "episodes", "tabletop rearrangement: push named objects across the line (MuJoCo)",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop" / "episodes-v1.jsonl",
            agents=("map-pusher", "frame-pusher", "random-pusher"),
            env_kwargs={"width": 160, "height": 120, "scan_frames": 8}, question=_Q_PUSH, headline_metric="success",
        ),
        Suite(
            "rearrange-v2", "episodes",
            "tabletop rearrangement on library tabletops (evaluation seeds): goals named by name, synonym, attribute or function",
            task="tabletop_rearrange", episodes_file=SEALED_FOLDER / "rearrange-episodes-v2.jsonl",
            agents=("map-pusher", "twin-pusher", "frame-pusher", "random-pusher"),
            env_kwargs=dict(REARRANGE_V2_ENV), default_encoder="embedded-v2", limit=REARRANGE_V2_LIMIT,
            question=_Q_PUSH, headline_metric="success",
        ),
        Suite(
            "search", "episodes", "object search in apartments: stop within 1 m of the described object",
            task="object_search", episodes_file=SCENES_ROOT / "household" / "episodes-v1.jsonl",
            agents=("map-navigator", "frame-searcher", "random-walker"),
            env_kwargs={"width": 160, "height": 120}, question=_Q_SEARCH, headline_metric="success",
        ),
        Suite(
            "search-v2", "episodes",
            "object search in library-filled apartments (evaluation seeds): goals named by name, synonym, attribute or function",
            task="object_search", episodes_file=SEALED_FOLDER / "search-episodes-v2.jsonl",
            agents=("map-navigator", "twin-navigator", "frame-searcher", "random-walker"),
            env_kwargs=dict(SEARCH_V2_ENV), default_encoder="embedded-v2", limit=SEARCH_V2_LIMIT,
            agent_limits={"frame-searcher": FRAME_SEARCHER_LIMIT}, question=_Q_SEARCH, headline_metric="success",
        ),
        Suite(
            "chain-v2", "episodes",
            "multi-goal search in library-filled apartments (sealed set): chains of 2-4 goals revealed one at a time; "
            "success per position in the chain (reached_k)",
            task="object_search", episodes_file=SEALED_FOLDER / "chain-episodes-v2.jsonl",
            agents=("map-navigator", "twin-navigator", "random-walker"),
            env_kwargs=dict(SEARCH_V2_ENV), default_encoder="embedded-v2", limit=CHAIN_V2_LIMIT,
            question="Does the map help the navigator reach several described objects, one after another?",
            headline_metric="success",
        ),
        Suite(
            "fetch-v2", "episodes",
            "explore, then fetch (sealed set): an exploration budget, then 2-4 goals revealed one at a time; success per "
            "position (reached_k)",
            task="object_search", episodes_file=SEALED_FOLDER / "fetch-episodes-v2.jsonl",
            agents=("map-navigator", "twin-navigator", "random-walker"), env_kwargs=dict(SEARCH_V2_ENV), default_encoder="embedded-v2",
            question="After exploring, does the map help the navigator fetch described objects one after another?",
            headline_metric="success",
        ),
        Suite(
            "search-v2-pybullet", "episodes",
            "search-v2 in PyBullet: the same sealed episodes, apartments and camera, rendered and loaded by PyBullet instead "
            "of MuJoCo (does an agent's result survive the change of simulator?)",
            task="object_search", episodes_file=SEALED_FOLDER / "search-episodes-v2.jsonl",
            agents=("map-navigator", "twin-navigator", "random-walker"),
            env_kwargs={**SEARCH_V2_ENV, "backend": "pybullet"}, default_encoder="embedded-v2", limit=SEARCH_V2_LIMIT,
            question="Does the navigator's search survive a change of renderer and physics (PyBullet against MuJoCo)?",
            headline_metric="success",
        ),
        Suite(
            "instruct-v2", "episodes",
            "instruction search (the paper's planner in the loop): needs, rooms and relations instead of object names, on 20 "
            "fresh apartments; a language planner told the map's rooms and objects against the same planner without them",
            task="object_search", episodes_file=INSTRUCT_FOLDER / "instruct-episodes-v2.jsonl",
            agents=("map-planner", "generic-planner", "oracle-searcher"),
            env_kwargs=dict(INSTRUCT_V2_ENV), default_encoder="embedded-v2", limit=INSTRUCT_V2_LIMIT,
            question="Does a language planner find what an instruction asks for better when it is told what the map holds?",
            headline_metric="success", baseline="generic-planner", verdicts=("map context helps", "map context hurts"),
        ),
        Suite("query", "maps", "text, image and click query localisation over fused tabletop maps (3D mIoU, detection accuracy)",
              question=_Q_QUERY, headline_metric="text_miou"),
        Suite("query-open", "maps",
              "open-vocabulary text queries over fused v2 tabletop maps: name, synonym, parent, colour, material, function, "
              "absent; split seen / held-out instance / held-out category (3D mIoU, accuracy at IoU 0.25, found rate)",
              default_encoder="embedded-v2", question=_Q_QUERY_OPEN, headline_metric="name_miou"),
        Suite("ablation", "maps", "pixel-feature ablation: global only, local only, no uniqueness, full (mAcc, f-mIoU)",
              **_ABLATION_CARD),
        Suite("spatial", "maps", "spatial questions from the scene graph: 3D map vs single RGB-D frame", **_SPATIAL_CARD),
        Suite("query-v2", "maps", "text, image and click query localisation over fused v2 tabletop maps (object library; 3D mIoU, "
              "detection accuracy)", default_encoder="embedded-v2", question=_Q_QUERY, headline_metric="text_miou"),
        Suite("ablation-v2", "maps", "pixel-feature ablation on v2 tabletops: global only, local only, no uniqueness, full "
              "(mAcc, f-mIoU)", default_encoder="embedded-v2", **_ABLATION_CARD),
        Suite("spatial-v2", "maps", "spatial questions from the scene graph of v2 apartments and tabletops: 3D map vs single "
              "RGB-D frame", default_encoder="embedded-v2", **_SPATIAL_CARD),
        Suite(
            "regression-rearrange", "episodes", "pinned tabletop episodes with calibrated success bounds, oracle perception (CI)",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop" / "episodes-v1.jsonl",
            agents=("map-pusher", "frame-pusher", "random-pusher", "oracle-pusher"),
            env_kwargs={"width": 128, "height": 96, "scan_frames": 6}, encoder="oracle",
            calibration_file=SCENES_ROOT / "calibration" / "tabletop-episodes-v1.jsonl", **calibrated_bounds("regression-rearrange"),
        ),
        Suite(
            "regression-rearrange-embedded", "episodes",
            "pinned tabletop episodes with calibrated success bounds, the shipped embedded perception (CI)",
            task="tabletop_rearrange", episodes_file=SCENES_ROOT / "tabletop" / "episodes-v1.jsonl",
            agents=("map-pusher", "frame-pusher"), env_kwargs={"width": 128, "height": 96, "scan_frames": 6}, encoder="embedded",
            calibration_file=SCENES_ROOT / "calibration" / "tabletop-episodes-v1.jsonl",
            **calibrated_bounds("regression-rearrange-embedded"),
        ),
        Suite(
            "regression-search", "episodes", "pinned household search episodes with calibrated success bounds, oracle perception (CI)",
            task="object_search", episodes_file=SCENES_ROOT / "household" / "episodes-v1.jsonl",
            agents=("map-navigator", "frame-searcher", "random-walker", "oracle-searcher"),
            env_kwargs={"width": 160, "height": 120}, encoder="oracle",
            calibration_file=SCENES_ROOT / "calibration" / "search-episodes-v1.jsonl", **calibrated_bounds("regression-search"),
        ),
        Suite(
            "regression-rearrange-v2", "episodes",
            "the headline tabletop pipeline gated: pinned v2 tabletop episodes (gate set), embedded-v2 perception and the "
            "shipped agent settings, calibrated success bounds (CI, -m headline_gate)",
            task="tabletop_rearrange", episodes_file=GATE_FOLDER / "rearrange-episodes-v2.jsonl",
            agents=("map-pusher", "twin-pusher", "frame-pusher", "random-pusher", "oracle-pusher"),
            env_kwargs=dict(REARRANGE_V2_ENV), encoder="embedded-v2",
            calibration_file=GATE_FOLDER / "rearrange-calibration-v2.jsonl", **calibrated_bounds("regression-rearrange-v2"),
        ),
        Suite(
            "regression-search-v2", "episodes",
            "the headline search pipeline gated: pinned v2 apartment searches (gate set), embedded-v2 perception and the "
            "shipped agent settings, calibrated success bounds (CI, -m headline_gate)",
            task="object_search", episodes_file=GATE_FOLDER / "search-episodes-v2.jsonl",
            agents=("map-navigator", "twin-navigator", "random-walker", "oracle-searcher"),
            env_kwargs=dict(SEARCH_V2_ENV), encoder="embedded-v2",
            calibration_file=GATE_FOLDER / "search-calibration-v2.jsonl", **calibrated_bounds("regression-search-v2"),
        ),
        Suite(
            "regression-search-v2-pybullet", "episodes",
            "the search gate's PyBullet slice: regression-search-v2's pinned and calibration searches run in PyBullet, "
            "oracle-open perception pinned (it gates the simulator: geometry, physics, depth, segmentation, the agents' "
            "control; the MuJoCo-trained tower's domain gap is measured in the sim-to-sim table instead), calibrated "
            "success bound (CI, -m gate); map-navigator alone: one bound more keeps every other bound of the "
            "family-wise gate as it was",
            task="object_search", episodes_file=GATE_FOLDER / "search-episodes-v2.jsonl",
            agents=("map-navigator",),
            env_kwargs={**SEARCH_V2_ENV, "backend": "pybullet"}, encoder="oracle-open",
            calibration_file=GATE_FOLDER / "search-calibration-v2.jsonl",
            **calibrated_bounds("regression-search-v2-pybullet"),
        ),
    )
}
"""Every suite by name."""

HEADLINE_GATE = ("regression-rearrange-v2", "regression-search-v2")
"""The regression suites that gate the headline pipeline (CI: ``python -m pytest -q -m headline_gate``)."""

DEFAULT_SUITES = ("query-open", "query-v2", "ablation-v2", "spatial-v2", "rearrange-v2", "search-v2", "chain-v2")
"""What ``cfharness run`` runs with no ``--suite``: the v2 world (object library, evaluation seeds)
for every suite: open-vocabulary, image and click queries, the feature ablation, spatial questions,
rearrangement and search. The v1 suites (``query``, ``ablation``, ``spatial``, ``rearrange``,
``search``) stay runnable by name."""


def suite_encoder(suite: Suite, run_encoder: str | None) -> str:
    """The perception a suite runs with: its pinned encoder, else the run's ``--encoder``, else
    the suite's default (the shipped tower of its world)."""
    return suite.encoder or run_encoder or suite.default_encoder


def suite_over(suite: Suite, name: str, episodes_file: Path) -> Suite:
    """``suite`` (its agents, environment settings and perception) over every episode of another
    file, named ``name``, with no limits, bounds or calibration file of its own: the suite's
    calibration and development runs."""
    return dataclasses.replace(suite, name=name, episodes_file=Path(episodes_file), limit=None, agent_limits={},
                               lower_bounds={}, upper_bounds={}, calibration_file=None)


def suite_episodes(suite: Suite) -> list[Episode]:
    """The episodes an episode suite may run, in file order: those of ``suite.episodes_file`` whose
    scene the split file does not reserve (:meth:`sim_envs.scenes.splits.Splits.is_reserved_scene`).

    Raises:
        HarnessError: ``suite`` has no episodes file (a map suite).
    """
    if suite.episodes_file is None:
        raise HarnessError(f"suite {suite.name!r} has no episodes file (a {suite.kind!r} suite)")
    split = splits()
    episodes = load_episodes(suite.episodes_file, scenes_root=suite.scenes_root).episodes
    if is_sealed_file(suite.episodes_file):
        verify_sealed(suite.episodes_file, {e.scene for e in episodes})
    if suite.task == "object_search":
        check_chains_reachable(episodes, where=str(suite.episodes_file), scenes_root=suite.scenes_root)
    if suite.scenes_root is not None:  # a user's own scenes: the split file reserves shipped ones only
        return list(episodes)
    return [e for e in episodes if not split.is_reserved_scene(e.scene)]


EPISODES_PREFIX = "episodes:"
"""A suite name that starts so names a user's episode file (:func:`episodes_suite`)."""
_SCENES_PART = ",scenes="
TASK_TEMPLATES = {"tabletop_rearrange": "rearrange-v2", "object_search": "search-v2"}
"""The built-in suite whose agents and environment settings a user's episodes of each task run with by default."""


def episodes_suite_name(episodes_file: str | os.PathLike, scenes: str | os.PathLike | None = None) -> str:
    """The suite name of a user's episode file (``cfharness run --episodes FILE [--scenes DIR]``):
    ``"episodes:FILE"`` or ``"episodes:FILE,scenes=DIR"``, paths as given."""
    return f"{EPISODES_PREFIX}{episodes_file}" + (f"{_SCENES_PART}{scenes}" if scenes is not None else "")


def episodes_suite(name: str) -> Suite:
    """The suite a user's episode file makes (``name`` from :func:`episodes_suite_name`): every
    episode of the file, validated as the shipped ones are (:func:`~sim_envs.scenes.episodes.load_episodes`:
    the header, each line's fields, the scenes resolved exactly, goal objects present, starts
    inside the apartment; search episodes reachable), scene references resolved under the
    ``scenes=`` folder (default: the shipped ``scenes/``), run with the agents and environment
    settings of the built-in suite :data:`TASK_TEMPLATES` names for the file's task (``--agent``
    and ``--encoder`` choose others), no limit and no regression bounds.

    Raises:
        HarnessError: the name is not of that form, or the file or scene folder is missing or
            invalid (the message names the file and line).
    """
    spec = name[len(EPISODES_PREFIX):]
    path, _, scenes = spec.partition(_SCENES_PART)
    if not name.startswith(EPISODES_PREFIX) or not path:
        raise HarnessError(f"expected a suite name 'episodes:FILE' (an episode file), got {name!r}")
    root = Path(scenes) if scenes else None
    if root is not None and not root.is_dir():
        raise HarnessError(f"--scenes: expected a folder of scene files, got {scenes!r} (no such folder)")
    try:
        task = load_episodes(path, scenes_root=root).task  # every line checked here, before any episode runs
    except (OSError, ValueError) as exc:
        raise HarnessError(f"--episodes: {exc}") from exc
    base = SUITES[TASK_TEMPLATES[task]]
    suite = suite_over(base, name, Path(path))
    env = {**base.env_kwargs, **({"scenes_root": str(root.resolve())} if root is not None else {})}
    return dataclasses.replace(suite, description=f"{task} episodes of {path} (agents and settings of {base.name})",
                               env_kwargs=env, scenes_root=root.resolve() if root is not None else None)


def get_suite(name: str) -> Suite:
    """The suite called ``name`` (a built-in one, or a user's episode file named
    ``episodes:FILE``: :func:`episodes_suite`); ``ValueError`` naming the nearest ones otherwise."""
    if name.startswith(EPISODES_PREFIX):
        return episodes_suite(name)
    return lookup(SUITES, name, "suite")
