"""Nothing lost, nothing silent (issue 41): every file reader answers bad input with a clear
error naming the file, the line and the field, before any allocation or hang.

One section per class of fault: exact scene references, duplicate JSON keys, only regular
files (size and depth limits first), array headers checked before allocation, big integers and
non-physical numbers. Every case writes a tiny file to ``tmp_path`` and pins the message.
"""

from __future__ import annotations

import io
import json
import os
import threading
import zipfile
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest
from numpy.lib import format as npy_format

from agents.spatial.llm import LLMParser, LLMParserConfig
from conceptfusion.errors import HarnessError, MapFormatError, MissingFileError, SceneFormatError, SimError
from conceptfusion.io_utils import MAX_RESULTS_BYTES, read_file_bytes, read_text_file
from conceptfusion.map.fusion import PointFusionMap
from conceptfusion.map.persistence import load_map, save_map
from conceptfusion.strict_json import MAX_INT_DIGITS, MAX_JSON_DEPTH, loads_strict
from harness.cli import main as cli_main
from harness.runner.results import (
    ResultsFormatError, append_record, load_results, make_record, read_run_config, repair_results, write_run_config,
)
from harness.runner.suites import calibrated_bounds
from sim_envs.scenes.episodes import SCENES_ROOT, EpisodeFormatError, load_episodes, resolve_scene
from sim_envs.scenes.format import load_scene, save_scene
from sim_envs.scenes.gen_tabletop import generate_tabletop
from sim_envs.scenes.household_format import MAX_MAGNITUDE
from sim_envs.scenes.splits import SplitError, load_splits

HEADER = {"format": "cf-episodes", "version": 1, "task": "tabletop_rearrange", "generator_seed": 0}
GOOD = {"episode_id": "e0", "scene": "tabletop-0007", "scene_seed": 7, "instruction": "push it",
        "goals": [{"object_id": "obj0", "side": "left"}], "start_pose": None, "max_steps": 6}
SEARCH_HEADER = {**HEADER, "task": "object_search"}
HOUSE = "household/household-0000.json"


def _write_eps(tmp_path, rows, name="eps.jsonl") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(r if isinstance(r, str) else json.dumps(r) for r in rows) + "\n")
    return p


def _scenes_root(tmp_path) -> Path:
    """A scenes root holding tabletop/t1.json (a valid scene) and nothing else."""
    root = tmp_path / "scenes"
    save_scene(generate_tabletop(1), root / "tabletop" / "t1.json")
    return root


def _rec(**over) -> dict:
    fields = dict(run_id="r1", suite="s", task="t", agent="a", encoder="e", episode_id="ep-0", seed=0, status="ok",
                  metrics={"success": True}, timings={"wall_s": 1.0})
    fields.update(over)
    return make_record(**fields)


def _search_row(**over) -> dict:
    house = json.loads((SCENES_ROOT / HOUSE).read_text())
    goal = house["objects"][0]["id"]
    return {**GOOD, "scene": HOUSE, "scene_seed": 0, "goals": [{"object_id": goal}], "start_pose": [0.5, 0.5, 0.0], **over}


# ------------------------------------------------------------------------- 1. exact scene references
@pytest.mark.parametrize("ref, message", [
    ("*", r"scene '\*': expected a path relative to the scenes root .*got glob character\(s\) \*"),
    ("household-000[0-9]", r"scene 'household-000\[0-9\]': .*got glob character\(s\) \[ \]"),
    ("tabletop/*.json", r"scene 'tabletop/\*\.json': .*glob character"),
    ("../outside.json", r"scene '\.\./outside\.json': .*got an absolute path, a backslash or '\.\.'"),
    ("/etc/passwd.json", r"scene '/etc/passwd\.json': .*got an absolute path"),
    ("a b", r"scene 'a b': expected a path relative to the scenes root"),
])
def test_scene_reference_is_exact_or_refused(tmp_path, ref, message):
    root = _scenes_root(tmp_path)
    p = _write_eps(tmp_path, [HEADER, {**GOOD, "scene": ref}])
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:line 2: episode 'e0': field 'scene': {message}"):
        load_episodes(p, scenes_root=root)


def test_glob_reference_used_to_load_another_scene(tmp_path):
    # "t*" used to match t1.json by rglob; now nothing is a pattern
    root = _scenes_root(tmp_path)
    with pytest.raises(SimError, match=r"glob character"):
        resolve_scene("t*", scenes_root=root)
    assert resolve_scene("tabletop/t1.json", scenes_root=root).id == "tabletop-0001"
    assert resolve_scene("t1", scenes_root=root).id == "tabletop-0001"  # an exact id still names its file


def test_symlink_out_of_the_scenes_root_is_refused(tmp_path):
    root = _scenes_root(tmp_path)
    save_scene(generate_tabletop(2), tmp_path / "elsewhere.json")
    (root / "link.json").symlink_to(tmp_path / "elsewhere.json")
    with pytest.raises(SimError, match=r"scene 'link\.json': .*outside the scenes root"):
        resolve_scene("link.json", scenes_root=root)


def test_missing_scene_file_and_ambiguous_id(tmp_path):
    root = _scenes_root(tmp_path)
    with pytest.raises(MissingFileError, match=r"scene file .*tabletop/t9\.json does not exist \(scene 'tabletop/t9\.json'"):
        resolve_scene("tabletop/t9.json", scenes_root=root)
    save_scene(generate_tabletop(1), root / "copy" / "t1.json")
    p = _write_eps(tmp_path, [HEADER, {**GOOD, "scene": "t1", "scene_seed": 1}])
    with pytest.raises(EpisodeFormatError, match=r"line 2: episode 'e0': field 'scene': scene 't1': 2 files are named t1\.json "
                                                 r"under .* \(copy/t1\.json, tabletop/t1\.json\); expected one"):
        load_episodes(p, scenes_root=root)


# ------------------------------------------------------------------------- 2. duplicate JSON keys
def test_scene_with_objects_twice_is_refused(tmp_path):
    doc = generate_tabletop(1).to_json()
    text = json.dumps(doc, indent=1)
    text = text[:-2] + ',\n "objects": []\n}'  # a second "objects", which json.loads would keep
    assert json.loads(text)["objects"] == []
    p = tmp_path / "s.json"
    p.write_text(text)
    with pytest.raises(SceneFormatError, match=r"s\.json:line 1: duplicate key 'objects' in one JSON object"):
        load_scene(p)


def test_duplicate_key_deep_in_a_scene_names_its_line(tmp_path):
    doc = generate_tabletop(1).to_json()
    lines = json.dumps(doc, indent=1).splitlines()
    k = next(i for i, ln in enumerate(lines) if '"yaw"' in ln)  # in objects[0]
    lines.insert(k + 1, lines[k])
    p = tmp_path / "s.json"
    p.write_text("\n".join(lines))
    opened = max(i for i in range(k) if lines[i].strip() == "{") + 1  # objects[0] opens there (1-based)
    with pytest.raises(SceneFormatError, match=rf"s\.json:line {opened}: duplicate key 'yaw'"):
        load_scene(p)


def test_duplicate_keys_in_episodes_results_run_settings_and_splits(tmp_path):
    line = json.dumps(GOOD)[:-1] + ', "scene": "tabletop-0008"}'
    with pytest.raises(EpisodeFormatError, match=r"eps\.jsonl:line 2: duplicate key 'scene'"):
        load_episodes(_write_eps(tmp_path, [HEADER, line]), check_scenes=False)
    res = tmp_path / "results.jsonl"
    rec = json.dumps(_rec())
    res.write_text(rec + "\n" + rec[:-1] + ', "seed": 1}\n')
    with pytest.raises(ResultsFormatError, match=r"results\.jsonl:line 2: duplicate key 'seed'"):
        load_results(res)
    run = tmp_path / "run"
    write_run_config(run, {"agents": ["a"]})
    (run / "run.json").write_text((run / "run.json").read_text().replace('"version": 1', '"version": 1, "version": 1'))
    with pytest.raises(ResultsFormatError, match=r"run\.json:line 1: duplicate key 'version'"):
        read_run_config(run)
    splits = tmp_path / "splits.json"
    splits.write_text('{"format": "cf-splits", "version": 1,\n "seeds": {}, "seeds": {}}')
    with pytest.raises(SplitError, match=r"splits\.json:line 1: duplicate key 'seeds'"):
        load_splits(splits)
    bounds = tmp_path / "bounds.json"
    bounds.write_text('{"suites": {"search": {"agents": {}}},\n "suites": {}}')
    with pytest.raises(HarnessError, match=r"bounds\.json:line 1: duplicate key 'suites'"):
        calibrated_bounds("search", bounds)


def test_distinct_keys_in_sibling_objects_are_fine():
    assert loads_strict('[{"a": 1}, {"a": 2}]', source="x", error=ValueError) == [{"a": 1}, {"a": 2}]


# ------------------------------------------------------------------ 3. regular files, size and depth
def _in_thread(fn, timeout=10.0):
    """Run ``fn`` in a thread; the exception it raised (or None), and whether it finished."""
    out: dict = {}

    def run():
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            out["exc"] = exc

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(timeout)
    return out.get("exc"), not t.is_alive()


def test_results_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "results.jsonl"
    os.mkfifo(fifo)
    try:
        for fn in (lambda: load_results(fifo), lambda: repair_results(fifo), lambda: append_record(fifo, _rec())):
            exc, finished = _in_thread(fn)
            assert finished, "reading a FIFO blocked"
            assert isinstance(exc, ResultsFormatError)
            assert "results.jsonl: expected a results file, got a FIFO (named pipe); only regular files are read" in str(exc)
    finally:
        try:  # unblock a reader left behind by a regression
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass


def test_results_symlinked_to_dev_zero_is_refused(tmp_path):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero on this system")
    p = tmp_path / "results.jsonl"
    p.symlink_to("/dev/zero")
    with pytest.raises(ResultsFormatError, match=r"results\.jsonl: expected a results file, got a character device "
                                                 r"\(a symlink to /dev/zero\)"):
        load_results(p)
    q = tmp_path / "s.json"
    q.symlink_to("/dev/zero")
    with pytest.raises(SceneFormatError, match=r"s\.json: expected a scene file, got a character device"):
        load_scene(q)


def test_episode_fifo_is_refused(tmp_path):
    fifo = tmp_path / "eps.jsonl"
    os.mkfifo(fifo)
    exc, finished = _in_thread(lambda: load_episodes(fifo))
    assert finished and isinstance(exc, EpisodeFormatError)
    assert "got a FIFO" in str(exc)


def test_size_limit_is_checked_before_reading(tmp_path):
    p = tmp_path / "big.json"
    p.write_bytes(b" " * 1000)
    with pytest.raises(SceneFormatError, match=r"big\.json: expected a scene file of at most 100 bytes, got 1000 bytes"):
        read_text_file(p, "scene file", SceneFormatError, max_bytes=100)
    assert read_file_bytes(p, "scene file", SceneFormatError, 1000) == b" " * 1000
    assert MAX_RESULTS_BYTES >= 2**30  # generous: a results file of a million records still reads


def test_deep_nesting_is_refused_naming_the_limit(tmp_path):
    p = tmp_path / "s.json"
    p.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(SceneFormatError, match=rf"s\.json:line 1: JSON nested 200000 levels deep; expected at most {MAX_JSON_DEPTH}"):
        load_scene(p)
    deep = '{"a": ' * (MAX_JSON_DEPTH + 1) + "1" + "}" * (MAX_JSON_DEPTH + 1)
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:line 2: JSON nested {MAX_JSON_DEPTH + 1} levels deep"):
        load_episodes(_write_eps(tmp_path, [HEADER, deep]), check_scenes=False)
    ok = '{"a": ' * MAX_JSON_DEPTH + "1" + "}" * MAX_JSON_DEPTH
    assert loads_strict(ok, source="x", error=ValueError)["a"]["a"]
    assert loads_strict('["[[[[", "{{{{"]', source="x", error=ValueError, max_depth=1) == ["[[[[", "{{{{"]  # strings


class _DeepReplyHandler(BaseHTTPRequestHandler):
    body = b'{"choices": ' + b"[" * 200_000 + b"]" * 200_000 + b"}"

    def do_POST(self):  # noqa: N802 - http.server's name
        self.rfile.read(int(self.headers.get("Content-Length", 0)))
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(self.body)))
        self.end_headers()
        self.wfile.write(self.body)

    def log_message(self, *args):
        pass


def test_llm_reply_nested_200000_deep_is_a_clear_cannot_parse():
    server = ThreadingHTTPServer(("127.0.0.1", 0), _DeepReplyHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        parser = LLMParser(LLMParserConfig(base_url=f"http://127.0.0.1:{server.server_address[1]}/v1", max_retries=0,
                                           retry_delay_s=0.0, timeout_s=10.0))
        result = parser.parse("How far is the chair from the sofa?")  # used to raise RecursionError
    finally:
        server.shutdown()
        server.server_close()
    assert not result.ok
    assert f"reply:line 1: JSON nested 200001 levels deep; expected at most {MAX_JSON_DEPTH}" in result.reason


# ------------------------------------------------------------------ 4. array headers before allocation
def _small_map() -> PointFusionMap:
    n, d, slots = 4, 3, 2
    geo = np.zeros((n, 10), np.float32)
    geo[:, 5] = geo[:, 9] = 1.0
    ids = np.full((n, slots), -1, np.int32)
    ids[:, 0] = np.arange(n)
    w = np.zeros((n, slots), np.float32)
    w[:, 0] = 1
    gram = np.zeros((n, 3), np.float32)
    gram[:, 0] = 1
    header = {"feature_dim": d, "num_points": n, "frames_integrated": 1,
              "config": {"dist_th": 0.05, "angle_th_deg": 20.0, "sigma": 0.6, "max_depth": None, "slots": slots}}
    bank = np.eye(n, d, dtype=np.float32) + np.float32(1e-3)
    return PointFusionMap.from_state_dict(header, {"geometry": geo, "feat_bank": bank, "feat_point_ids": ids,
                                                   "feat_point_w": w, "feat_point_gram": gram, "feat_point_sq": np.ones(n)})


def _claiming_map(tmp_path, member="geometry.npy", shape=(10**11, 10)) -> Path:
    """A saved map whose ``member`` header claims ``shape`` (the data stays as it was)."""
    src = save_map(_small_map(), tmp_path / "good.npz")
    out = tmp_path / "huge.npz"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == member:
                f = io.BytesIO(data)
                npy_format.read_magic(f)
                _, _, dtype = npy_format.read_array_header_1_0(f)
                body = data[f.tell():]
                head = io.BytesIO()
                npy_format.write_array_header_1_0(head, {"descr": npy_format.dtype_to_descr(dtype), "fortran_order": False,
                                                         "shape": shape})
                data = head.getvalue() + body
            zout.writestr(info.filename, data)
    return out


def test_map_header_claiming_1e12_elements_is_refused_before_allocation(tmp_path):
    p = _claiming_map(tmp_path)
    assert p.stat().st_size < 4096
    with pytest.raises(MapFormatError, match=r"huge\.npz: not a readable map file: member 'geometry\.npy' claims shape "
                                             r"\(100000000000, 10\) of float32 \(4000000000000 bytes\), but holds 160 bytes"):
        load_map(p)


def test_map_header_claiming_fewer_elements_is_refused(tmp_path):
    p = _claiming_map(tmp_path, member="feat_point_sq.npy", shape=(2,))
    with pytest.raises(MapFormatError, match=r"member 'feat_point_sq\.npy' claims shape \(2,\) of float64 \(16 bytes\), "
                                             r"but holds 32 bytes"):
        load_map(p)


def test_view_refuses_the_lying_map_with_exit_2(tmp_path, capsys):
    p = _claiming_map(tmp_path)
    assert cli_main(["view", str(p), "--encoder", "color"]) == 2
    err = capsys.readouterr().err
    assert "cfharness view:" in err and "member 'geometry.npy' claims shape (100000000000, 10)" in err


# ------------------------------------------------------------- 5. big integers, non-physical values
def test_5000_digit_integer_names_file_line_and_field(tmp_path):
    big = "9" * 5000
    line = json.dumps(GOOD).replace('"scene_seed": 7', f'"scene_seed": {big}')
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:line 2: field 'scene_seed': expected an integer of at most "
                                                 rf"{MAX_INT_DIGITS} digits, got one of 5000 digits"):
        load_episodes(_write_eps(tmp_path, [HEADER, line]), check_scenes=False)
    text = json.dumps(generate_tabletop(1).to_json(), indent=1).replace('"seed": 1', f'"seed": -{big}')
    (tmp_path / "s.json").write_text(text)
    seed_line = next(i for i, ln in enumerate(text.splitlines(), 1) if '"seed"' in ln)
    with pytest.raises(SceneFormatError, match=rf"s\.json:line {seed_line}: field 'seed': expected an integer of at most"):
        load_scene(tmp_path / "s.json")
    res = tmp_path / "results.jsonl"
    res.write_text(json.dumps(_rec()).replace('"seed": 0', f'"seed": {big}') + "\n")
    with pytest.raises(ResultsFormatError, match=r"results\.jsonl:line 1: field 'seed': expected an integer"):
        load_results(res)


def test_start_pose_500_m_outside_the_apartment_names_the_bounds(tmp_path):
    p = _write_eps(tmp_path, [SEARCH_HEADER, _search_row(start_pose=[500.0, 3.0, 0.0])])
    with pytest.raises(EpisodeFormatError, match=r"eps\.jsonl:line 2: episode 'e0': field 'start_pose': start pose "
                                                 r"\(500\.00, 3\.00\) is outside the apartment's bounds x in "
                                                 r"\[-?\d+\.\d\d, \d+\.\d\d\], y in \[-?\d+\.\d\d, \d+\.\d\d\]"):
        load_episodes(p)
    assert load_episodes(_write_eps(tmp_path, [SEARCH_HEADER, _search_row()], "ok.jsonl")).episodes[0].start_pose == (0.5, 0.5, 0.0)


@pytest.mark.parametrize("value", [1e300, -1e300, 2 * MAX_MAGNITUDE])
def test_absurd_coordinates_are_refused(tmp_path, value):
    doc = json.loads(json.dumps(generate_tabletop(1).to_json()))
    doc["objects"][0]["position"][0] = value
    (tmp_path / "s.json").write_text(json.dumps(doc))
    with pytest.raises(SceneFormatError, match=rf"s\.json: objects\[0\]\.position: expected 3 numbers within "
                                               rf"\+-{MAX_MAGNITUDE:g} \(metres\)"):
        load_scene(tmp_path / "s.json")
    doc = json.loads(json.dumps(generate_tabletop(1).to_json()))
    doc["objects"][1]["yaw"] = value
    (tmp_path / "s.json").write_text(json.dumps(doc))
    with pytest.raises(SceneFormatError, match=r"objects\[1\]\.yaw: expected a number within"):
        load_scene(tmp_path / "s.json")
    p = _write_eps(tmp_path, [SEARCH_HEADER, _search_row(start_pose=[value, 0.0, 0.0])])
    with pytest.raises(EpisodeFormatError, match=rf"eps\.jsonl:line 2: 'start_pose' expected \[x, y, yaw\] within "
                                                 rf"\+-{MAX_MAGNITUDE:g}"):
        load_episodes(p, check_scenes=False)
