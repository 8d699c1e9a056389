"""Bad files get a clear answer (issue 13): scene, episode, map and results readers name the file,
the line (JSON Lines) and the field, and never let a raw numpy/Python error or a NaN through.

Every case writes a tiny file to ``tmp_path`` and pins the message.
"""

from __future__ import annotations

import copy
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from conceptfusion.errors import MapFormatError, MissingFileError, SceneFormatError, SimError
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import load_map, save_map
from harness.cli import main as cli_main
from harness.runner.results import (
    ResultsFormatError, append_record, load_results, load_runs, make_record, repair_results,
)
from sim_envs.scenes.episodes import SCENES_ROOT, EpisodeFormatError, load_episodes
from sim_envs.scenes.format import load_scene, scene_from_json
from sim_envs.scenes.gen_tabletop import generate_tabletop

ROOT = Path(__file__).resolve().parents[2]


# ------------------------------------------------------------------------------------ scenes
def _tabletop_doc() -> dict:
    return json.loads(json.dumps(generate_tabletop(1).to_json()))


def _household_doc() -> dict:
    return json.loads((SCENES_ROOT / "household" / "household-0000.json").read_text())


def _write_scene(tmp_path, doc, name="s.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(doc))
    return p


def test_every_shipped_scene_still_loads():
    from sim_envs.scenes.sealed import MANIFEST_NAME

    # scene folders (top-level files are splits and the like; the sealed set's manifest is no scene)
    files = sorted(f for f in (ROOT / "scenes").glob("*/*.json") if f.name != MANIFEST_NAME)
    assert len(files) > 100
    for f in files:
        load_scene(f)


def test_scene_nan_yaw(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][2]["yaw"] = float("nan")  # json.dumps writes NaN, json.loads reads it
    p = _write_scene(tmp_path, doc)
    with pytest.raises(SceneFormatError, match=r"s\.json: objects\[2\]\.yaw: expected a finite number, got nan"):
        load_scene(p)


def test_scene_infinite_position_and_table(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["position"][0] = float("inf")
    with pytest.raises(SceneFormatError, match=r"s\.json: objects\[0\]\.position: expected 3 finite numbers"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _tabletop_doc()
    doc["table"]["center"][2] = float("-inf")
    with pytest.raises(SceneFormatError, match=r"s\.json: table\.center: expected 3 finite numbers"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_table_as_a_list(tmp_path):
    doc = _tabletop_doc()
    doc["table"] = [0, 0, 0.4]
    with pytest.raises(SceneFormatError, match=r"s\.json: table: expected an object \{center, size, material\} or null, got list"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_line_as_a_string(tmp_path):
    doc = _tabletop_doc()
    doc["line"] = "x = 0"
    with pytest.raises(SceneFormatError, match=r"s\.json: line: expected an object \{start, end\} or null, got str"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_line_of_zero_length(tmp_path):
    doc = _tabletop_doc()
    doc["line"] = {"start": [0.0, 0.1], "end": [0.0, 0.1]}
    with pytest.raises(SceneFormatError, match=r"s\.json: line: start and end coincide"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_unknown_table_material(tmp_path):
    doc = _tabletop_doc()
    doc["table"]["material"] = "marble"
    with pytest.raises(SceneFormatError, match=r"s\.json: table\.material: unknown material 'marble'; known materials: .*'wood'"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_object_off_the_table(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][1]["position"][0] = 2.0  # the table top spans x in [-0.6, 0.6]
    with pytest.raises(SceneFormatError, match=r"objects\[1\] \('obj1', .*\): off the table: its centre \(2\.000, .*outside the table top"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_object_floating_above_the_table(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["position"][2] += 0.05
    with pytest.raises(SceneFormatError, match=r"objects\[0\] \('obj0', .*\): floats: base at z=0\.450, but the table top is at z=0\.400"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_object_within_the_tolerance_loads(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["position"][2] += 0.005  # 5 mm: within the 1 cm tolerance
    assert load_scene(_write_scene(tmp_path, doc)).objects[0].position[2] == pytest.approx(0.405)


def test_scene_household_object_floating_above_its_support(tmp_path):
    doc = _household_doc()
    obj = next(o for o in doc["objects"] if o.get("support", "floor") != "floor")
    obj["position"][2] += 0.2
    with pytest.raises(SceneFormatError, match=rf"s\.json: object {obj['id']!r} .*floats: base at z="):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_numeric_ids_are_refused(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["id"] = 5
    with pytest.raises(SceneFormatError, match=r"s\.json: objects\[0\]\.id: expected a non-empty string, got 5"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _tabletop_doc()
    doc["id"] = 7
    with pytest.raises(SceneFormatError, match=r"s\.json: id: expected a string, got 7"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _household_doc()
    doc["furniture"][0]["id"] = 3
    with pytest.raises(SceneFormatError, match=r"s\.json: furniture\[0\]\.id: expected a non-empty string, got 3"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_binary_file_names_the_file(tmp_path):
    p = tmp_path / "b.json"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe")
    with pytest.raises(SceneFormatError, match=r"b\.json:line 1: not a scene file: not UTF-8 text \(byte 0x89 at offset 0\)"):
        load_scene(p)


@pytest.mark.parametrize("field, value, message", [
    ("position", "0 0 0.4", r"objects\[0\]\.position: expected a list of 3 numbers, got '0 0 0.4'"),
    ("position", ["0.1", "0.1", "0.4"], r"objects\[0\]\.position: expected a list of 3 numbers"),
    ("position", [0.1, 0.1], r"objects\[0\]\.position: expected 3 finite numbers, got \[0.1, 0.1\]"),
    ("size", "big", r"objects\[0\]\.size: expected a list of 3 numbers, got 'big'"),
    ("size", [0.1, 0.1, 0.1, 0.1], r"objects\[0\]\.size: expected 3 finite numbers"),
    ("size", [0.1, -0.1, 0.1], r"objects\[0\]\.size: expected positive sizes"),
    ("size", [0.1, True, 0.1], r"objects\[0\]\.size: expected a list of 3 numbers"),
    ("yaw", "0.3", r"objects\[0\]\.yaw: expected a finite number, got '0.3'"),
    ("phrases", "a mug", r"objects\[0\]\.phrases: expected a list, got str"),
    ("name", ["red", "mug"], r"objects\[0\]\.name: expected a non-empty string"),
    ("asset", ["mug"], r"objects\[0\]\.asset: unknown asset \['mug'\]"),
    ("support", 3, r"objects\[0\]\.support: expected a non-empty string, got 3"),
])
def test_scene_object_field_types(tmp_path, field, value, message):
    doc = _tabletop_doc()
    doc["objects"][0][field] = value
    with pytest.raises(SceneFormatError, match=rf"s\.json: {message}"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_negative_table_size(tmp_path):
    doc = _tabletop_doc()
    doc["table"]["size"] = [1.2, -0.8, 0.05]
    with pytest.raises(SceneFormatError, match=r"s\.json: table\.size: expected positive sizes, got \[1\.2, -0\.8, 0\.05\]"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_unknown_field_is_a_typo(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["yaww"] = doc["objects"][0].pop("yaw")
    with pytest.raises(SceneFormatError, match=r"objects\[0\]: unknown field 'yaww'; did you mean 'yaw'"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _tabletop_doc()
    doc["tabel"] = doc.pop("table")
    with pytest.raises(SceneFormatError, match=r"s\.json: unknown field 'tabel'; did you mean 'table'"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_objects_not_a_list_and_bad_seed_and_version(tmp_path):
    doc = _tabletop_doc()
    doc["objects"] = {"obj0": {}}
    with pytest.raises(SceneFormatError, match=r"s\.json: objects: expected a list, got dict"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _tabletop_doc()
    doc["seed"] = "7"
    with pytest.raises(SceneFormatError, match=r"s\.json: seed: expected an integer, got '7'"):
        load_scene(_write_scene(tmp_path, doc))
    doc = _tabletop_doc()
    doc["version"] = True
    with pytest.raises(SceneFormatError, match=r"s\.json: version: expected an integer format version >= 1, got True"):
        load_scene(_write_scene(tmp_path, doc))


def test_scene_household_fields(tmp_path):
    cases = [
        (lambda d: d["walls"][0].update(thickness=float("nan")), r"walls\[0\]\.thickness: expected a finite number, got nan"),
        (lambda d: d["walls"][0].update(height="tall"), r"walls\[0\]\.height: expected a finite number, got 'tall'"),
        (lambda d: d["walls"][0].update(height=-2.5), r"walls\[0\]\.height: expected a positive number, got -2\.5"),
        (lambda d: d["furniture"][0].update(yaw=float("inf")), r"furniture\[0\]\.yaw: expected a finite number, got inf"),
        (lambda d: d["furniture"][0].update(shelf_heights=["low"]), r"furniture\[0\]\.shelf_heights\[0\]: expected a finite number"),
        (lambda d: d["furniture"][0].update(category=["counter"]), r"furniture\[0\] \('f0'\): unknown furniture kind \['counter'\]"),
        (lambda d: d["rooms"][0].update(floor_material=["tile"]), r"rooms\[0\]\.floor_material: unknown material \['tile'\]"),
        (lambda d: d.update(walls={"wall0": {}}), r"walls: expected a list, got dict"),
    ]
    for edit, message in cases:
        doc = _household_doc()
        edit(doc)
        with pytest.raises(SceneFormatError, match=rf"s\.json: {message}"):
            load_scene(_write_scene(tmp_path, doc))


def test_scene_missing_file_and_folder(tmp_path):
    with pytest.raises(MissingFileError, match=r"scene file not found: .*nope\.json"):
        load_scene(tmp_path / "nope.json")
    with pytest.raises(FileNotFoundError):  # still what callers have always caught
        load_scene(tmp_path / "nope.json")
    with pytest.raises(SceneFormatError, match=r"expected a scene file, got a folder"):
        load_scene(tmp_path)


def test_scene_errors_are_sim_errors_and_value_errors():
    d = _tabletop_doc()
    d["objects"][0]["yaw"] = None
    with pytest.raises(SimError):
        scene_from_json(d)
    with pytest.raises(ValueError, match=r"scene: objects\[0\]\.yaw"):
        scene_from_json(copy.deepcopy(d))


# ------------------------------------------------------------------------------------ episodes
HEADER = {"format": "cf-episodes", "version": 1, "task": "tabletop_rearrange", "generator_seed": 0}
GOOD = {"episode_id": "e0", "scene": "tabletop-0007", "scene_seed": 7, "instruction": "push it",
        "goals": [{"object_id": "obj0", "side": "left"}], "start_pose": None, "max_steps": 6}


def _write_eps(tmp_path, rows, name="eps.jsonl") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(r if isinstance(r, str) else json.dumps(r) for r in rows) + "\n")
    return p


def test_episodes_good_file_loads(tmp_path):
    assert len(load_episodes(_write_eps(tmp_path, [HEADER, GOOD])).episodes) == 1


@pytest.mark.parametrize("header, message", [
    ({**HEADER, "version": True}, r"line 1: expected version <= 3 \(an integer >= 1\), got True"),
    ({**HEADER, "version": 0}, r"line 1: expected version <= 3 \(an integer >= 1\), got 0"),
    ({**HEADER, "generator_seed": "0"}, r"line 1: 'generator_seed' expected an integer or null, got '0'"),
    ({**HEADER, "taks": "x"}, r"line 1: header: unknown field 'taks'; did you mean 'task'"),
    ([1, 2], r"line 1: expected a header with format 'cf-episodes', got \[1, 2\]"),
])
def test_episodes_bad_header(tmp_path, header, message):
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:{message}"):
        load_episodes(_write_eps(tmp_path, [header, GOOD]))


@pytest.mark.parametrize("edit, message", [
    ({"scene_seed": "7"}, r"line 2: 'scene_seed' expected an integer, got '7'"),
    ({"scene_seed": -1}, r"line 2: 'scene_seed' expected >= 0, got -1"),
    ({"max_steps": 6.0}, r"line 2: 'max_steps' expected an integer, got 6\.0"),
    ({"max_steps": True}, r"line 2: 'max_steps' expected an integer, got True"),
    ({"episode_id": 3}, r"line 2: 'episode_id' expected a non-empty string, got 3"),
    ({"instruction": ""}, r"line 2: 'instruction' expected a non-empty string, got ''"),
    ({"start_pose": [0, 0, True]}, r"line 2: 'start_pose' expected null or \[x, y, yaw\]"),
    ({"goals": {"object_id": "obj0"}}, r"line 2: 'goals' expected a non-empty list"),
    ({"goals": [{"object_id": 0, "side": "left"}]}, r"line 2: goals\[0\] expected \{'object_id': str, ...\}"),
    ({"goals": [{"object_id": "obj0", "side": "left"}, {"object_id": "obj0", "side": "right"}]},
     r"line 2: goals\[1\]\.object_id 'obj0' repeats goals\[0\]"),
    ({"goals": [{"object_id": "obj0", "sid": "left"}]}, r"line 2: goals\[0\]: unknown field 'sid'; did you mean 'side'"),
    ({"max_step": 6}, r"line 2: unknown field 'max_step'; did you mean 'max_steps'"),
])
def test_episodes_bad_field(tmp_path, edit, message):
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:{message}"):
        load_episodes(_write_eps(tmp_path, [HEADER, {**GOOD, **edit}]), check_scenes=False)


def test_episodes_nan_is_not_json(tmp_path):
    line = json.dumps({**GOOD, "start_pose": [0.0, float("nan"), 0.0]})
    with pytest.raises(EpisodeFormatError, match=r"eps\.jsonl:line 2: not valid JSON \(NaN is not a number JSON allows\)"):
        load_episodes(_write_eps(tmp_path, [HEADER, line]), check_scenes=False)


def test_episodes_side_on_a_search_goal(tmp_path):
    header = {**HEADER, "task": "object_search"}
    row = {**GOOD, "goals": [{"object_id": "obj0", "side": "left"}], "start_pose": [0.0, 0.0, 0.0]}
    with pytest.raises(EpisodeFormatError, match=r"line 2: goals\[0\]\.side expected no side for task 'object_search'"):
        load_episodes(_write_eps(tmp_path, [header, row]), check_scenes=False)


def test_episodes_unknown_scene_reference(tmp_path):
    with pytest.raises(EpisodeFormatError, match=r"eps\.jsonl:line 3: episode 'e1': field 'scene': scene 'kitchen-9': no file kitchen-9\.json"):
        load_episodes(_write_eps(tmp_path, [HEADER, GOOD, {**GOOD, "episode_id": "e1", "scene": "kitchen-9"}]))


def test_episodes_scene_file_that_is_bad(tmp_path):
    doc = _tabletop_doc()
    doc["objects"][0]["yaw"] = "north"
    (tmp_path / "scenes").mkdir()
    _write_scene(tmp_path / "scenes", doc, "bad.json")
    p = _write_eps(tmp_path, [HEADER, {**GOOD, "scene": "bad.json"}])
    with pytest.raises(EpisodeFormatError, match=r"line 2: episode 'e0': field 'scene': .*bad\.json: objects\[0\]\.yaw: expected a finite number"):
        load_episodes(p, scenes_root=tmp_path / "scenes")


def test_episodes_binary_missing_and_empty(tmp_path):
    p = tmp_path / "bin.jsonl"
    p.write_bytes(json.dumps(HEADER).encode() + b"\n\xff\xfe\x00junk\n")
    with pytest.raises(EpisodeFormatError, match=r"bin\.jsonl:line 2: not an episode file: not UTF-8 text \(byte 0xff at offset \d+\)"):
        load_episodes(p)
    with pytest.raises(MissingFileError, match=r"episode file not found: .*none\.jsonl"):
        load_episodes(tmp_path / "none.jsonl")
    (tmp_path / "empty.jsonl").write_text("")
    with pytest.raises(EpisodeFormatError, match=r"empty\.jsonl: expected a header line, got an empty file"):
        load_episodes(tmp_path / "empty.jsonl")


# ------------------------------------------------------------------------------------ maps
def _map(n=5, d=4, slots=2) -> PointFusionMap:
    """A small map built from a state dict: ``n`` points, one feature each."""
    rng = np.random.default_rng(0)
    geo = np.zeros((n, 10), np.float32)
    geo[:, :3] = rng.normal(size=(n, 3))
    geo[:, 5] = 1.0  # normals +z
    geo[:, 6:9] = 128
    geo[:, 9] = 1.0
    bank = rng.normal(size=(n, d)).astype(np.float32)
    bank /= np.linalg.norm(bank, axis=1, keepdims=True)
    ids = np.full((n, slots), -1, np.int32)
    ids[:, 0] = np.arange(n)
    w = np.zeros((n, slots), np.float32)
    w[:, 0] = 1
    tri = slots * (slots + 1) // 2
    gram = np.zeros((n, tri), np.float32)
    gram[:, 0] = 1
    header = {"feature_dim": d, "num_points": n, "frames_integrated": 1,
              "config": {"dist_th": 0.05, "angle_th_deg": 20.0, "sigma": 0.6, "max_depth": None, "slots": slots}}
    arrays = {"geometry": geo, "feat_bank": bank, "feat_point_ids": ids, "feat_point_w": w, "feat_point_gram": gram,
              "feat_point_sq": np.ones(n)}
    return PointFusionMap.from_state_dict(header, arrays)


def _saved(tmp_path, edit_header=None, edit_arrays=None) -> Path:
    src = save_map(_map(), tmp_path / "good.npz")
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(bytes(arrays.pop("header")).decode())
    if edit_header:
        edit_header(header)
    if edit_arrays:
        edit_arrays(arrays)
    out = tmp_path / "m.npz"
    np.savez(out, header=np.frombuffer(json.dumps(header).encode(), np.uint8), **arrays)
    return out


def test_map_good_file_loads_and_scores(tmp_path):
    m = load_map(_saved(tmp_path))
    assert len(m) == 5 and np.isfinite(m.scores(np.ones(4))).all()


def test_map_npy_file(tmp_path):
    np.save(tmp_path / "a.npy", np.zeros(3))
    with pytest.raises(MapFormatError, match=r"a\.npy: not a readable map file: this is a single-array \.npy file"):
        load_map(tmp_path / "a.npy")


def test_map_text_file_does_not_mention_allow_pickle(tmp_path):
    (tmp_path / "t.npz").write_text("hello, I am text")
    with pytest.raises(MapFormatError, match=r"t\.npz: not a readable map file: expected an \.npz archive written by "
                                             r"save_map, but the file starts with b'hello, I'") as info:
        load_map(tmp_path / "t.npz")
    assert "pickle" not in str(info.value)
    (tmp_path / "e.npz").write_bytes(b"")
    with pytest.raises(MapFormatError, match=r"e\.npz: not a readable map file: the file is empty"):
        load_map(tmp_path / "e.npz")


def test_map_object_array_does_not_mention_allow_pickle(tmp_path):
    header = json.dumps({"format": "conceptfusion-map", "version": 1}).encode()
    np.savez(tmp_path / "o.npz", header=np.frombuffer(header, np.uint8), geometry=np.array([{"a": 1}], dtype=object))
    with pytest.raises(MapFormatError, match=r"o\.npz: not a readable map file: an entry holds Python objects") as info:
        load_map(tmp_path / "o.npz")
    assert "allow_pickle" not in str(info.value)


def test_map_wrong_geometry_width(tmp_path):
    p = _saved(tmp_path, edit_arrays=lambda a: a.update(geometry=a["geometry"][:, :7]))
    with pytest.raises(MapFormatError, match=r"m\.npz: array 'geometry' expected 10 columns .*got shape \(5, 7\)"):
        load_map(p)


def test_map_missing_header_key(tmp_path):
    p = _saved(tmp_path, edit_header=lambda h: h.pop("frames_integrated"))
    with pytest.raises(MapFormatError, match=r"m\.npz: header lacks the field 'frames_integrated'"):
        load_map(p)


def test_map_extra_config_key(tmp_path):
    p = _saved(tmp_path, edit_header=lambda h: h["config"].update(radius=3))
    with pytest.raises(MapFormatError, match=r"m\.npz: header field 'config': expected the keys .*; unknown \['radius'\]"):
        load_map(p)


@pytest.mark.parametrize("edit, message", [
    (lambda h: h.update(num_points="5"), r"header field 'num_points': expected int, got '5'"),
    (lambda h: h.update(feature_dim=0), r"header field 'feature_dim': expected >= 1, got 0"),
    (lambda h: h["config"].update(slots=2.5), r"header field 'config\.slots': expected an integer >= 1, got 2\.5"),
    (lambda h: h["config"].update(sigma=-1), r"header field 'config\.sigma': expected a positive finite number, got -1"),
    (lambda h: h["config"].pop("sigma"), r"header field 'config': expected the keys .*; missing \['sigma'\]"),
    (lambda h: h.update(colour="red"), r"header: unknown field\(s\) \['colour'\]"),
])
def test_map_bad_header_fields(tmp_path, edit, message):
    with pytest.raises(MapFormatError, match=rf"m\.npz: {message}"):
        load_map(_saved(tmp_path, edit_header=edit))


def test_map_nan_positions_and_features(tmp_path):
    def nan_pos(a):
        a["geometry"][2, 1] = np.nan

    with pytest.raises(MapFormatError, match=r"m\.npz: array 'geometry' holds NaN or infinite values \(first at index \[2, 1\]\)"):
        load_map(_saved(tmp_path, edit_arrays=nan_pos))

    def inf_feat(a):
        a["feat_bank"][0, 3] = np.inf

    with pytest.raises(MapFormatError, match=r"m\.npz: array 'feat_bank' holds NaN or infinite values"):
        load_map(_saved(tmp_path, edit_arrays=inf_feat))


def test_map_header_not_json_and_missing_file(tmp_path):
    header = np.frombuffer(b"\xff\xfe{", np.uint8)
    np.savez(tmp_path / "h.npz", header=header)
    with pytest.raises(MapFormatError, match=r"h\.npz: header: not valid JSON text"):
        load_map(tmp_path / "h.npz")
    with pytest.raises(MissingFileError, match=r"map file not found: .*none\.npz"):
        load_map(tmp_path / "none.npz")


# ------------------------------------------------------------------------------------ results
def _rec(episode_id="ep-0", **over) -> dict:
    fields = dict(run_id="r1", suite="s", task="t", agent="a", encoder="e", episode_id=episode_id, seed=0,
                  status="ok", metrics={"success": True, "spl": 0.5}, timings={"wall_s": 1.0})
    fields.update(over)
    return make_record(**fields)


def _results(tmp_path, lines, name="run") -> Path:
    run = tmp_path / name
    run.mkdir(exist_ok=True)
    (run / "results.jsonl").write_text("".join((ln if isinstance(ln, str) else json.dumps(ln)) + "\n" for ln in lines))
    return run


@pytest.mark.parametrize("edit, message", [
    ({"seed": "abc"}, r"line 2: field 'seed': expected an integer, got 'abc'"),
    ({"seed": True}, r"line 2: field 'seed': expected an integer, got True"),
    ({"status": "weird"}, r"line 2: field 'status': expected one of \('ok', 'failed', 'timeout'\), got 'weird'"),
    ({"metrics": {"success": "yes"}}, r"line 2: field 'metrics\['success'\]': expected a finite number, true/false or null, got 'yes'"),
    ({"metrics": {"spl": float("nan")}}, r"line 2: field 'metrics\['spl'\]': expected a finite number, true/false or null, got nan"),
    ({"timings": {"wall_s": "1s"}}, r"line 2: field 'timings\['wall_s'\]': expected a finite number, got '1s'"),
    ({"agent": 3}, r"line 2: field 'agent': expected a string, got 3"),
    ({"metrics": [1]}, r"line 2: field 'metrics': expected an object, got \[1\]"),
    ({"extras": {"path_xy": [[0.0, float("inf")]]}}, r"line 2: field \"extras\['path_xy'\]\[0\]\[1\]\": NaN or infinity"),
    ({"sucess": True}, r"line 2: unknown field\(s\) \['sucess'\]"),
])
def test_results_bad_field_is_refused_with_file_line_and_field(tmp_path, edit, message):
    run = _results(tmp_path, [_rec("ep-0"), {**_rec("ep-1"), **edit}])
    with pytest.raises(ResultsFormatError, match=rf"results\.jsonl: {message}"):
        load_results(run / "results.jsonl")
    with pytest.raises(ResultsFormatError, match=message):  # resume's gate refuses it too
        repair_results(run / "results.jsonl")


def test_results_missing_field(tmp_path):
    rec = _rec()
    del rec["status"]
    run = _results(tmp_path, [rec])
    with pytest.raises(ResultsFormatError, match=r"results\.jsonl: line 1: missing field 'status'"):
        load_results(run / "results.jsonl")


def test_results_junk_line_is_refused_before_resume_appends(tmp_path):
    run = _results(tmp_path, [_rec("ep-0"), "junk from an editor", _rec("ep-1"), _rec("ep-2")])
    path = run / "results.jsonl"
    before = path.read_bytes()
    with pytest.raises(ResultsFormatError, match=r"results\.jsonl: holds 1 corrupt line\(s\) .*line 2: text 'junk from an editor'.*"
                                                 r"not appending after them: fix or delete line\(s\) 2 and resume again"):
        repair_results(path)
    assert path.read_bytes() == before  # nothing changed
    with pytest.warns(UserWarning, match=r"line 2: skipping a corrupt record"):  # a report still reads it
        assert len(load_results(path)) == 3


def test_results_resume_refuses_junk_and_bad_records(tmp_path):
    from harness.runner.results import write_run_config
    from harness.runner.run import RunConfig, run_suites

    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial")
    for name, bad, message in [("junk", "{half a record", r"line 2: text '\{half a record'"),
                               ("seed", {**_rec("ep-1"), "seed": "abc"}, r"line 2: field 'seed'")]:
        run = _results(tmp_path, [_rec("ep-0"), bad, _rec("ep-2")], name=name)
        write_run_config(run, {"run_id": "r1", "settings": config.settings(), "backend": "serial"})
        before = (run / "results.jsonl").read_bytes()
        with pytest.raises(ResultsFormatError, match=message):
            run_suites(config, run, resume=True, progress=False)
        assert (run / "results.jsonl").read_bytes() == before


def test_results_half_written_tail_is_still_repaired(tmp_path):
    run = _results(tmp_path, [_rec("ep-0")])
    path = run / "results.jsonl"
    path.write_bytes(path.read_bytes() + b'{"format": "cf-res')
    assert repair_results(path) == len(b'{"format": "cf-res')
    append_record(path, _rec("ep-1"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert [r["episode_id"] for r in load_results(path)] == ["ep-0", "ep-1"]


def test_results_binary_and_text_files_are_not_results(tmp_path):
    p = tmp_path / "bin.jsonl"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\n\x00\x01\x02\n")
    with pytest.raises(ResultsFormatError, match=r"bin\.jsonl: line 1: corrupt record: binary data, not a JSON record.*"
                                                 r"this is not a results file"):
        load_results(p)
    t = tmp_path / "notes.jsonl"
    t.write_text("first note\nsecond note\n")
    with pytest.raises(ResultsFormatError, match=r"notes\.jsonl: line 1: corrupt record: text 'first note'.*not a results file"):
        load_results(t)


def test_load_runs(tmp_path):
    with pytest.raises(MissingFileError, match=r"nowhere: no such run folder or results file"):
        load_runs([tmp_path / "nowhere"])
    (tmp_path / "bare").mkdir()
    with pytest.raises(MissingFileError, match=r"bare: no results\.jsonl here; is it a run folder\?"):
        load_runs([tmp_path / "bare"])
    run = _results(tmp_path, [])
    with pytest.raises(ResultsFormatError, match=r"no records in .*run \(empty results file\?\)"):
        load_runs([run])
    assert len(load_runs([_results(tmp_path, [_rec()], name="ok")])) == 1


# --------------------------------------------------------------------- report / compare CLI
def _cli(capsys, *argv) -> tuple[int, str]:
    code = cli_main(list(argv))
    return code, capsys.readouterr().err


def test_report_missing_folder_exits_2(tmp_path, capsys):
    code, err = _cli(capsys, "report", str(tmp_path / "nowhere"))
    assert code == 2
    assert err.strip().splitlines()[-1].startswith(f"cfharness report: write_report: no results at {tmp_path / 'nowhere'}")


def test_report_empty_results_exits_2(tmp_path, capsys):
    run = _results(tmp_path, [])
    code, err = _cli(capsys, "report", str(run))
    assert code == 2
    assert err.strip().splitlines()[-1] == "cfharness report: write_report: the runs hold no records yet (empty results files?)"


def test_report_binary_results_exits_2(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.jsonl").write_bytes(b"\x00\x01\x02\nPK\x03\x04\x00\n\xff\xff")
    code, err = _cli(capsys, "report", str(run))
    assert code == 2
    assert "cfharness report: " in err and "line 1: corrupt record: binary data" in err and "not a results file" in err


def test_report_bad_record_exits_2(tmp_path, capsys):
    run = _results(tmp_path, [{**_rec(), "success": "yes"}])
    code, err = _cli(capsys, "report", str(run))
    assert code == 2
    assert "cfharness report: " in err and "results.jsonl: line 1: unknown field(s) ['success']" in err


def test_compare_missing_folder_exits_2(tmp_path, capsys):
    code, err = _cli(capsys, "compare", str(tmp_path / "nowhere"), "--a", "x", "--b", "y")
    assert code == 2
    assert err.strip().splitlines()[-1] == f"cfharness compare: {tmp_path / 'nowhere'}: no such run folder or results file"


def test_compare_empty_and_bad_results_exit_2(tmp_path, capsys):
    run = _results(tmp_path, [])
    code, err = _cli(capsys, "compare", str(run), "--a", "x", "--b", "y")
    assert code == 2 and "cfharness compare: no records in" in err
    bad = _results(tmp_path, [{**_rec(), "status": "weird"}], name="bad")
    code, err = _cli(capsys, "compare", str(bad), "--a", "x", "--b", "y")
    assert code == 2 and "line 1: field 'status': expected one of" in err


def test_report_and_compare_still_work(tmp_path, capsys):
    recs = [_rec(f"ep-{i}", agent=a, metrics={"success": (i + k) % 2 == 0}) for i in range(4) for k, a in enumerate("ab")]
    run = _results(tmp_path, recs)
    assert cli_main(["compare", str(run), "--a", "a", "--b", "b"]) == 0
    assert json.loads(capsys.readouterr().out)
    assert cli_main(["report", str(run), "--out", str(tmp_path / "rep")]) == 0
    assert (tmp_path / "rep" / "report.md").is_file()
