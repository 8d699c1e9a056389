"""The built-in agents, registered by name (see :mod:`agents.registry`).

Perception is chosen per agent with ``encoder``:

* ``"oracle"`` (privileged): ground-truth segmentation labelled with the MiniLM text embedding of
  each object's name (:class:`conceptfusion.perception.featurizer.OracleFeaturizer`), for upper
  bounds and regression tests that must not depend on perception;
* ``"oracle-open"`` (privileged): ground-truth segmentation and ground-truth grounding of
  descriptions (:class:`conceptfusion.perception.featurizer.GroundedOracleFeaturizer`): a
  description is found exactly where the objects answering to it are (name, synonym,
  attribute, function, parent group), for upper bounds on the v2 episodes;
* ``"embedded"`` (default): the shipped image tower + MiniLM text tower with RGB-D mask proposals;
* any other encoder registry spec (``"hf:..."``, ``"onnx:DIR"``, ``"color"``) with ``proposer``.

Either way the mapper is built by :func:`make_mapper` (that is :func:`conceptfusion.make_mapper`)
from a :class:`~conceptfusion.perception.featurizer.PerceptionSpec`, as the map suites build theirs.

=================  ===================  ==========  ======================================
name               task                 map         what
=================  ===================  ==========  ======================================
map-pusher         tabletop_rearrange   yes         scan -> map -> median -> push, re-check
twin-pusher        tabletop_rearrange   no (twin)   same scan, each frame perceived alone, same pushes
frame-pusher       tabletop_rearrange   no (2.5D)   same, from the current frame only
random-pusher      tabletop_rearrange   no          random pushes
oracle-pusher      tabletop_rearrange   privileged  ground-truth poses (solvability check)
oracle-searcher    object_search        privileged  ground-truth floor plan and goal (solvability check)
map-navigator      object_search        yes         map, query, OMPL plan, pure pursuit
twin-navigator     object_search        no (twin)   same grid, frontiers, planner; current frame only
frame-searcher     object_search        no (2.5D)   current frame only, reactive wandering
generic-planner    object_search        yes         instruction -> language planner alone -> navigator
map-planner        object_search        yes         instruction + the map's rooms and objects -> planner
random-walker      object_search        no          random velocities
=================  ===================  ==========  ======================================
"""

from __future__ import annotations

import conceptfusion.mapper
from agents.concept_map import ConceptMapper
from agents.spec import AgentSpec, Option, register_agent
from conceptfusion.perception.featurizer import SEARCH_PROPOSER, FrameFeaturizer, PerceptionSpec

__all__ = ["make_mapper", "planner_options"]


def make_mapper(
    perception: PerceptionSpec | str | FrameFeaturizer = "embedded", proposer: str = "rgbd", *, setting: str = "tabletop",
    **config,
) -> ConceptMapper:
    """The agents' mapper: :func:`conceptfusion.make_mapper` (the one builder of mappers, with the
    encoder's calibrated score floor for ``setting`` on), which see for the arguments.

    ``semantic_views``: 0 fuses concept vectors (the map agents); ``k`` keeps each of the last
    ``k`` frames' apart (the matched map-free twins, see :class:`~conceptfusion.mapper.MapperConfig`).

    Example::

        from agents import make_mapper

        mapper = make_mapper("color")            # any --encoder spec, a registered one too
        mapper.integrate(frame)                  # a conceptfusion.RGBDFrame
        result = mapper.locate("red box")        # regions, relevancy, found or not

    Raises:
        UnknownNameError: unknown encoder or proposer name (naming the nearest valid ones).
    """
    return conceptfusion.mapper.make_mapper(perception, proposer, setting=setting, **config)


PUSHER_TWIN_VIEWS = 64
"""Frames the pusher twin keeps apart: more than any scan has (it starts a new map every step, so
it holds exactly the step's scan and fixed frame)."""


def _pusher(mapper: ConceptMapper, use_scan: bool, **settings):
    from agents.pusher import MapPusher, PusherConfig

    return MapPusher(mapper, PusherConfig(**settings), use_scan=use_scan)


def _map_pusher(encoder: str = "embedded", proposer: str = "rgbd", scan: bool = True, assume_present: bool = True,
                name_only_fallback: bool = True, identify: bool = True):
    return _pusher(make_mapper(encoder, proposer), scan, assume_present=assume_present, name_only_fallback=name_only_fallback,
                   identify=identify)


def _twin_pusher(encoder: str = "embedded", proposer: str = "rgbd", assume_present: bool = True, name_only_fallback: bool = True,
                 identify: bool = True):
    return _pusher(make_mapper(encoder, proposer, semantic_views=PUSHER_TWIN_VIEWS), True, assume_present=assume_present,
                   name_only_fallback=name_only_fallback, identify=identify)


def _frame_pusher(encoder: str = "embedded", proposer: str = "rgbd", assume_present: bool = True, name_only_fallback: bool = True,
                  identify: bool = True):
    return _pusher(make_mapper(encoder, proposer, persistent=False), False, assume_present=assume_present,
                   name_only_fallback=name_only_fallback, identify=identify)


def _navigator(encoder: str, proposer: str, seed: int, semantic_views: int, **settings):
    from agents.navigator import MapNavigator, NavigatorConfig

    return MapNavigator(make_mapper(encoder, proposer, setting="search", semantic_views=semantic_views), NavigatorConfig(**settings),
                        seed=seed)


def _map_navigator(encoder: str = "embedded", proposer: str = SEARCH_PROPOSER, seed: int = 0, integrate_every: int = 1,
                   keyframe_move: float = 0.3, keyframe_turn_deg: float = 40.0, goal_tolerance: float = 0.05,
                   presume_after: int = 200):
    return _navigator(encoder, proposer, seed, 0, integrate_every=integrate_every, keyframe_move=keyframe_move,
                      keyframe_turn_deg=keyframe_turn_deg, goal_tolerance=goal_tolerance, presume_after=presume_after)


def _twin_navigator(encoder: str = "embedded", proposer: str = SEARCH_PROPOSER, seed: int = 0, integrate_every: int = 1,
                    keyframe_move: float = 0.3, keyframe_turn_deg: float = 40.0, goal_tolerance: float = 0.05,
                    presume_after: int = 200, hold_sighting: bool = True, look_again: bool = True):
    return _navigator(encoder, proposer, seed, 1, integrate_every=integrate_every, keyframe_move=keyframe_move,
                      keyframe_turn_deg=keyframe_turn_deg, goal_tolerance=goal_tolerance, presume_after=presume_after,
                      hold_sighting=hold_sighting, look_again=look_again)


def _frame_searcher(encoder: str = "embedded", proposer: str = SEARCH_PROPOSER):
    from agents.baselines import FrameSearcher

    return FrameSearcher(make_mapper(encoder, proposer, persistent=False, setting="search"))


def _known_encoder(spec: str) -> bool:
    PerceptionSpec.parse(spec)  # UnknownNameError naming the nearest encoders
    return True


def _known_proposer(spec: str) -> bool:
    PerceptionSpec.parse("color", proposer=spec)  # UnknownNameError naming the nearest proposers
    return True


_PERCEPTION = {
    "encoder": Option(str, "embedded", _known_encoder, "an encoder spec, see cfharness list"),
    "proposer": Option(str, "rgbd", _known_proposer, "a mask proposer spec"),
}
_SEARCH_PERCEPTION = {**_PERCEPTION, "proposer": Option(str, SEARCH_PROPOSER, _known_proposer, "a mask proposer spec")}
"""The search agents' perception options: their proposals default to the small-object ones (see
:data:`~conceptfusion.perception.featurizer.SEARCH_PROPOSER`)."""
_SEED = Option.at_least(int, 0, 0)
_PRESENCE = {"assume_present": Option(bool, True), "name_only_fallback": Option(bool, True), "identify": Option(bool, True)}
"""The pushers' options for objects their instruction names (:class:`~agents.pusher.PusherConfig`)."""

register_agent(AgentSpec(
    "map-pusher", _map_pusher, "tabletop_rearrange",
    "ConceptFusion map from an orbit scan; pushes each named object's median across the line; re-checks and retries",
    {**_PERCEPTION, "scan": Option(bool, True), **_PRESENCE}, uses_map=True,
))
register_agent(AgentSpec(
    "twin-pusher", _twin_pusher, "tabletop_rearrange",
    "matched map-free twin of map-pusher: the same scan and fixed frames, each perceived alone (the best single frame "
    "answers), the same push planner and rules; geometry fused, concept vectors not",
    {**_PERCEPTION, **_PRESENCE}, twin_of="map-pusher",
))
register_agent(AgentSpec(
    "frame-pusher", _frame_pusher, "tabletop_rearrange",
    "single-frame (2.5D) pusher: the same perception on the current camera frame only, no map",
    {**_PERCEPTION, **_PRESENCE},
))
register_agent(AgentSpec(
    "random-pusher", "agents.baselines:RandomPusher", "tabletop_rearrange",
    "random straight pushes on the table, random number of pushes", {"seed": _SEED, "max_pushes": Option.at_least(int, 4, 1)},
))
register_agent(AgentSpec(
    "oracle-pusher", "agents.oracle_push:OraclePushAgent", "tabletop_rearrange",
    "privileged scripted pusher on ground-truth poses (proves episodes solvable)", {}, privileged=True,
))
register_agent(AgentSpec(
    "oracle-searcher", "agents.oracle_search:OracleSearchAgent", "object_search",
    "privileged scripted searcher on the ground-truth floor plan and goal box (proves episodes solvable)", {}, privileged=True,
))
_NAVIGATOR_OPTIONS = {
    **_SEARCH_PERCEPTION, "seed": _SEED, "integrate_every": Option.at_least(int, 1, 1),
    "keyframe_move": Option.at_least(float, 0.3, 0.0), "keyframe_turn_deg": Option.at_least(float, 40.0, 0.0),
    "goal_tolerance": Option.at_least(float, 0.05, 0.01), "presume_after": Option.at_least(int, 200, 0)}
"""The options of the map navigator and its twin (:class:`~agents.navigator.NavigatorConfig`)."""

register_agent(AgentSpec(
    "map-navigator", _map_navigator, "object_search",
    "ConceptFusion map built online; goal query, OMPL path to the goal or a frontier, pure pursuit, stop",
    dict(_NAVIGATOR_OPTIONS), uses_map=True,
))
register_agent(AgentSpec(
    "twin-navigator", _twin_navigator, "object_search",
    "matched map-free twin of map-navigator (CLIP-on-Wheels style): the same occupancy grid, frontiers, OMPL planner, "
    "stop and presume rules, with recognition on the current frame only and the goal's last sighting kept; "
    "in a chain it looks again for each later goal",
    {**_NAVIGATOR_OPTIONS, "hold_sighting": Option(bool, True), "look_again": Option(bool, True)}, twin_of="map-navigator",
))
def planner_options(planner: str, planner_url: str = "", planner_model: str = "") -> dict:
    """The keyword arguments of :func:`~agents.instruct.planner.make_planner` from the planner agents'
    options (a chat server's key from the environment variable ``CF_PLANNER_API_KEY``)."""
    import os

    if planner == "chat":
        key = os.environ.get("CF_PLANNER_API_KEY")
        return {"base_url": planner_url, "model": planner_model, **({"api_key": key} if key else {})}
    if planner_url or planner_model:
        raise ValueError(f"planner_url and planner_model are for planner='chat', got planner={planner!r}")
    return {}


def _planner_agent(use_map_context: bool, encoder: str, proposer: str, seed: int, planner: str, planner_url: str,
                   planner_model: str, replan_every: int, **navigator):
    from agents.instruct.agent import InstructionAgent, InstructionAgentConfig
    from agents.instruct.planner import make_planner

    options = planner_options(planner, planner_url, planner_model)

    return InstructionAgent(_navigator(encoder, proposer, seed, 0, **navigator), make_planner(planner, **options),
                            InstructionAgentConfig(use_map_context=use_map_context, replan_every=replan_every))


def _generic_planner(encoder: str = "embedded", proposer: str = SEARCH_PROPOSER, seed: int = 0, planner: str = "offline",
                     planner_url: str = "", planner_model: str = "", replan_every: int = 8, **navigator):
    return _planner_agent(False, encoder, proposer, seed, planner, planner_url, planner_model, replan_every, **navigator)


def _map_planner(encoder: str = "embedded", proposer: str = SEARCH_PROPOSER, seed: int = 0, planner: str = "offline",
                 planner_url: str = "", planner_model: str = "", replan_every: int = 8, **navigator):
    return _planner_agent(True, encoder, proposer, seed, planner, planner_url, planner_model, replan_every, **navigator)


def _known_planner(name: str) -> bool:
    from agents.instruct.planner import PLANNERS

    if name not in PLANNERS:
        from conceptfusion.names import unknown_name_error

        raise unknown_name_error("language planner", name, PLANNERS, n=2, listing=f"valid: {', '.join(PLANNERS)}")
    return True


register_agent(AgentSpec(
    "frame-searcher", _frame_searcher, "object_search",
    "map-free searcher: checks each frame with the same perception, drives to what it sees, wanders otherwise",
    dict(_SEARCH_PERCEPTION),
))
_PLANNER_OPTIONS = {
    **_NAVIGATOR_OPTIONS, "planner": Option(str, "offline", _known_planner, "a language planner: offline or chat"),
    "planner_url": Option(str, "", None, "chat planner: the server's base URL (http://host:port/v1)"),
    "planner_model": Option(str, "", None, "chat planner: the model name the server expects"),
    "replan_every": Option.at_least(int, 8, 1)}
"""The planner agents' options: the navigator's, the planner backend (a chat server's key comes
from ``CF_PLANNER_API_KEY``) and how often the map-context agent asks again."""

register_agent(AgentSpec(
    "generic-planner", _generic_planner, "object_search",
    "language planner on the instruction alone (general knowledge, no map context), then the map navigator searches for "
    "its proposals in turn; the paper's planner without a map",
    dict(_PLANNER_OPTIONS), uses_map=True,
))
register_agent(AgentSpec(
    "map-planner", _map_planner, "object_search",
    "language planner told the rooms and objects its map holds (and asking the map spatial questions) as it explores, "
    "then the map navigator drives to its choice; the paper's ConceptFusion planner in the loop",
    dict(_PLANNER_OPTIONS), uses_map=True,
))
register_agent(AgentSpec(
    "random-walker", "agents.baselines:RandomWalker", "object_search",
    "random velocity commands, random stop", {"seed": _SEED, "p_stop": Option.at_least(float, 0.01, 0.0, 1.0)},
))
