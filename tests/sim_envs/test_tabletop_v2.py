"""Tabletop v2: object descriptions, the generator, the shipped scenes and episodes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conceptfusion.errors import SimError
from sim_envs.assets.library import catalogue
from sim_envs.scenes.descriptions import DESCRIPTION_KINDS, candidates, describe, referents
from sim_envs.scenes.episodes import Episode, EpisodeSet, Goal, episodes_text, load_episodes, resolve_scene
from sim_envs.scenes.format import Scene, SceneObject, Table, scene_from_json
from sim_envs.scenes.gen_tabletop_v2 import MAX_FOOTPRINT, MAX_HEIGHT, UNSTABLE_CATEGORIES, generate_tabletop_v2, instance_pool
from sim_envs.scenes.splits import splits
from sim_envs.scenes.tabletop_v2_episodes import push_check


def _obj(i: int, instance_id: str) -> SceneObject:
    inst = catalogue().instances[instance_id]
    return SceneObject(f"obj{i}", inst.category, inst.category, inst.asset, inst.color, (0.0, 0.1 * i, 0.4), 0.0, (0.1, 0.1, 0.1))


def test_describe_kinds_on_a_small_scene():
    mug0, mug1, cup, hammer = _obj(0, "mug-000"), _obj(1, "mug-001"), _obj(2, "cup-000"), _obj(3, "hammer-002")
    objs = [mug0, mug1, cup, hammer]
    rng = np.random.default_rng(0)
    assert describe(mug0, objs, "name", rng) is None  # two mugs
    assert describe(hammer, objs, "name", rng) == "the hammer"
    assert describe(cup, objs, "name", rng) is None  # a mug is also called "cup"
    assert set(candidates(mug0, objs, "attribute")) == {f"the {mug0.color} mug", "the ceramic mug"}
    assert candidates(hammer, objs, "parent") == ("the hand tool", "the tool")
    assert candidates(hammer, objs, "function") == ("a tool to drive nails",)
    assert describe(mug0, objs, "function", rng) is None  # both mugs are for hot drinks
    # synonyms that contradict the object's material are not offered
    assert "the paper cup" not in candidates(cup, objs, "synonym")
    with pytest.raises(ValueError, match="unknown description kind"):
        describe(hammer, objs, "smell", rng)
    with pytest.raises(TypeError, match="numpy.random.Generator"):
        describe(hammer, objs, "name", 3)


def test_descriptions_are_unique_and_deterministic():
    ids = list(catalogue().instances)
    for seed in range(20):
        rng = np.random.default_rng(seed)
        objs = [_obj(i, ids[int(k)]) for i, k in enumerate(rng.choice(len(ids), size=8, replace=False))]
        for o in objs:
            for kind in DESCRIPTION_KINDS:
                a = describe(o, objs, kind, np.random.default_rng(seed))
                assert a == describe(o, objs, kind, np.random.default_rng(seed))
                if a is not None:
                    assert [r.id for r in referents(a, objs)] == [o.id]


# ------------------------------------------------------------------------------------ generator
SCENES = Path(__file__).resolve().parents[2] / "scenes"
V2 = SCENES / "tabletop-v2" / "episodes-v2.jsonl"
SEALED = SCENES / "sealed-v2" / "rearrange-episodes-v2.jsonl"
EVAL_LO, EVAL_HI = splits().seeds["evaluation"]


def test_generator_is_deterministic_and_keeps_its_constraints():
    cat = catalogue()
    for seed in range(EVAL_LO, EVAL_LO + 12):
        scene = generate_tabletop_v2(seed)
        assert scene.to_json() == generate_tabletop_v2(seed).to_json()
        assert 4 <= len(scene.objects) <= 12
        scene_from_json(scene.to_json(), source="generated")  # on the table, no overlaps, known assets
        assert len({o.name for o in scene.objects}) == len(scene.objects)
        for o in scene.objects:
            inst = cat.instances[o.asset[len("lib:"):]]
            assert "furniture" not in cat.ancestors(inst.category) and inst.category not in UNSTABLE_CATEGORIES
            assert max(o.size[:2]) <= MAX_FOOTPRINT and o.size[2] <= MAX_HEIGHT
            lo, hi = o.footprint()
            assert lo[0] > 0 or hi[0] < 0  # off the dividing line x = 0
        assert scene.extras["seed_role"] == "evaluation"


def test_generator_respects_the_split():
    lo, _ = splits().seeds["tower_train"]
    train = set(splits().instances_of("train"))
    for seed in range(lo, lo + 8):
        assert {o.asset[len("lib:"):] for o in generate_tabletop_v2(seed).objects} <= train
    assert {i.id for i in instance_pool("evaluation")} > {i.id for i in instance_pool("tower_train")}
    with pytest.raises(SimError, match="seed 7: lies in no seed range"):
        generate_tabletop_v2(7)


def test_push_check_refuses_a_blocked_corridor():
    table = Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05))
    z = table.top_z
    can = _obj(0, "can-000")
    target = SceneObject("obj0", can.name, can.category, can.asset, can.color, (-0.12, 0.1, z), 0.0, (0.07, 0.07, 0.12))
    scene = Scene("t", "tabletop", 0, table, (target,), ((0.0, -0.4), (0.0, 0.4)))
    assert push_check(scene, 0, "right").ok
    blocker = SceneObject("obj1", "x", can.category, can.asset, can.color, (0.1, 0.1, z), 0.0, (0.07, 0.07, 0.12))
    blocked = Scene("t", "tabletop", 0, table, (target, blocker), scene.line)
    assert push_check(blocked, 0, "right").reason == "corridor meets obj1"
    flat = Scene("t", "tabletop", 0, table, (SceneObject("obj0", "x", can.category, can.asset, can.color, (-0.12, 0.1, z), 0.0, (0.07, 0.07, 0.02)),), scene.line)
    assert push_check(flat, 0, "right").reason.startswith("height")


# ------------------------------------------------------------------------------------ shipped data
def test_shipped_v2_episodes_load_and_use_evaluation_seeds_only():
    eps = load_episodes(V2)
    assert len(eps.episodes) >= 150
    assert V2.read_text().splitlines()[0] == json.dumps(eps.header())
    assert {len(e.goals) for e in eps.episodes} == {1, 2}
    assert {e.description_kind for e in eps.episodes} == {"name", "synonym", "attribute", "function"}
    files = sorted((SCENES / "tabletop-v2").glob("*.json"))
    assert {f"tabletop-v2/{f.name}" for f in files} == {e.scene for e in eps.episodes}
    for f in files:
        assert EVAL_LO <= json.loads(f.read_text())["seed"] < EVAL_HI
    for e in eps.episodes:
        assert EVAL_LO <= e.scene_seed < EVAL_HI
        scene = resolve_scene(e.scene, e.scene_seed)
        for g in e.goals:
            assert g.description_kind == e.description_kind and g.description in e.instruction
            assert [o.id for o in referents(g.description, scene.objects)] == [g.object_id]


def test_goal_descriptions_round_trip_and_v1_stays_version_1():
    ep = Episode("e", "tabletop-v2/x.json", 300000, "push the mug to the left of the line",
                 (Goal("obj0", "left", "the mug", "name"),), None, 6, "name")
    text = episodes_text(EpisodeSet("tabletop_rearrange", 0, (ep,)))
    assert json.loads(text.splitlines()[0])["version"] == 2
    assert json.loads(text.splitlines()[1])["goals"] == [{"object_id": "obj0", "side": "left", "description": "the mug", "description_kind": "name"}]
    v1 = (SCENES / "tabletop" / "episodes-v1.jsonl").read_text().splitlines()[0]
    assert json.loads(v1)["version"] == 1



def test_bad_goal_description_kind_names_the_line_and_field(tmp_path):
    from sim_envs.scenes.episodes import EpisodeFormatError

    lines = V2.read_text().splitlines()[:2]
    rec = json.loads(lines[1])
    rec["goals"][0]["description_kind"] = "smell"
    bad = tmp_path / "bad.jsonl"
    bad.write_text(lines[0] + "\n" + json.dumps(rec) + "\n")
    with pytest.raises(EpisodeFormatError, match=r"bad.jsonl:line 2: goals\[0\].description_kind expected null or one of"):
        load_episodes(bad, scenes_root=SCENES)


def test_oracle_solves_v2_episodes_on_mujoco_and_the_suite_runs_them():
    import gymnasium as gym

    import sim_envs  # noqa: F401  (registers the environments)
    from agents.oracle_push import OraclePushAgent
    from harness.runner.suites import DEFAULT_SUITES, get_suite
    from harness.runner.tasks import EpisodeJob, run_episode

    suite = get_suite("rearrange-v2")
    assert suite.episodes_file == SEALED and suite.task == "tabletop_rearrange" and "rearrange-v2" in DEFAULT_SUITES
    eps = load_episodes(SEALED)
    rec = run_episode(EpisodeJob("t", "rearrange-v2", "tabletop_rearrange", "oracle-pusher", {}, eps.episodes[0], 0, {"width": 32, "height": 24}))
    assert rec["status"] == "ok", rec.get("error")
    assert rec["metrics"]["success"]
    pair = next(i for i, e in enumerate(eps.episodes) if len(e.goals) == 2)
    env = gym.make("cf/TabletopRearrange-v0", episodes=str(SEALED), width=32, height=24).unwrapped
    try:
        obs, info = env.reset(seed=pair, options={"episode_index": pair})
        agent, done = OraclePushAgent(), False
        while not done:
            obs, reward, terminated, truncated, info = env.step(agent.act(obs, info))
            done = terminated or truncated
        assert info["success"], (pair, info["evaluation"])
    finally:
        env.close()


def test_panda_reach_map():
    pytest.importorskip("pybullet")
    from sim_envs.pybullet.reach import PandaReach

    reach = PandaReach(Table((0.0, 0.0, 0.375), (1.2, 0.8, 0.05)))
    try:
        top = 0.42
        assert reach.reachable([[0.0, 0.1, top], [0.55, 0.38, top]]).tolist() == [True, False]
    finally:
        reach.close()
