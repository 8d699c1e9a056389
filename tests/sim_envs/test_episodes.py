"""The episode dataset format: loading, validation errors, atomic writing, the shipped episodes."""

import json
from pathlib import Path

import pytest

from sim_envs.scenes.episodes import (
    SCENES_ROOT, Episode, EpisodeFormatError, EpisodeSet, Goal, generate_tabletop_episodes, load_episodes,
    resolve_scene, save_episodes,
)
from sim_envs.envs.rearrange_eval import signed_line_distance

REPO = Path(__file__).resolve().parents[2]
SHIPPED = REPO / "scenes" / "tabletop" / "episodes-v1.jsonl"
HEADER = {"format": "cf-episodes", "version": 1, "task": "tabletop_rearrange", "generator_seed": 0}
GOOD = {
    "episode_id": "e0", "scene": "tabletop-0007", "scene_seed": 7, "instruction": "push it",
    "goals": [{"object_id": "obj0", "side": "right"}], "start_pose": None, "max_steps": 6,
}


def _write(tmp_path, lines) -> Path:
    p = tmp_path / "eps.jsonl"
    p.write_text("\n".join(x if isinstance(x, str) else json.dumps(x) for x in lines) + "\n")
    return p


def test_round_trip_through_the_writer(tmp_path):
    eps = EpisodeSet("object_search", 3, (Episode("s0", "house-1", 1, "find the mug", (Goal("obj2"),), (1.0, -2.0, 0.5), 500),))
    p = save_episodes(eps, tmp_path / "sub" / "search.jsonl")
    back = load_episodes(p, check_scenes=False)
    assert back == eps
    assert json.loads(p.read_text().splitlines()[0]) == {"format": "cf-episodes", "version": 1, "task": "object_search", "generator_seed": 3}
    assert not list(p.parent.glob(".*tmp"))  # no temporary file left behind


def test_corrupt_line_is_named_by_file_and_number(tmp_path):
    p = _write(tmp_path, [HEADER, GOOD, "{not json"])
    with pytest.raises(EpisodeFormatError, match=r"eps\.jsonl:line 3: not valid JSON"):
        load_episodes(p)
    p = _write(tmp_path, [HEADER, {**GOOD, "max_steps": "six"}])
    with pytest.raises(EpisodeFormatError, match=r"line 2: 'max_steps' expected an integer, got 'six'"):
        load_episodes(p)
    p = _write(tmp_path, [HEADER, {**GOOD, "goals": [{"object_id": "obj0", "side": "up"}]}])
    with pytest.raises(EpisodeFormatError, match=r"line 2: goals\[0\]\.side expected one of"):
        load_episodes(p)


def test_missing_object_id_is_a_clear_error(tmp_path):
    p = _write(tmp_path, [HEADER, GOOD, {**GOOD, "episode_id": "e1", "goals": [{"object_id": "obj99", "side": "left"}]}])
    with pytest.raises(EpisodeFormatError, match=r"line 3: episode 'e1' names object 'obj99', which scene 'tabletop-0007' lacks"):
        load_episodes(p)


def test_header_and_duplicates_are_checked(tmp_path):
    with pytest.raises(EpisodeFormatError, match="expected a header with format 'cf-episodes'"):
        load_episodes(_write(tmp_path, [GOOD]))
    with pytest.raises(EpisodeFormatError, match="expected task in"):
        load_episodes(_write(tmp_path, [{**HEADER, "task": "dance"}]))
    with pytest.raises(EpisodeFormatError, match="line 3: duplicate episode_id 'e0'"):
        load_episodes(_write(tmp_path, [HEADER, GOOD, GOOD]))
    with pytest.raises(EpisodeFormatError, match="line 2: episode 'e0': .*nowhere.json does not exist"):
        load_episodes(_write(tmp_path, [HEADER, {**GOOD, "scene": "tabletop/nowhere.json"}]))


def test_shipped_episodes_load_and_regenerate_identically():
    from scenes.make_tabletop_episodes import COUNT, GENERATOR_SEED, build_files

    eps = load_episodes(SHIPPED)
    assert eps.task == "tabletop_rearrange" and len(eps.episodes) >= 50
    files = build_files(GENERATOR_SEED, COUNT)
    for rel, text in files.items():
        assert (SCENES_ROOT / rel).read_text() == text, rel
    for ep in eps.episodes:
        scene = resolve_scene(ep.scene, ep.scene_seed)
        assert 1 <= len(ep.goals) <= 2 and ep.start_pose is None
        for g in ep.goals:  # every target starts on the other side of the line
            d = signed_line_distance(scene, [scene.object(g.object_id).position[:2]])[0]
            assert (d < 0) == (g.side == "right") and scene.object(g.object_id).name in ep.instruction


def test_generator_is_seeded():
    a, _ = generate_tabletop_episodes(5, 3)
    b, _ = generate_tabletop_episodes(5, 3)
    c, _ = generate_tabletop_episodes(6, 3)
    assert a == b and a != c and len({e.scene for e in a.episodes}) == 3
