"""A researcher's own episodes: ``cfharness run --episodes FILE [--scenes DIR]`` validates the file
as the shipped ones are, runs it with the agents and settings of the built-in suite of its task,
and resumes like any run."""

import json
import re
import shutil

import pytest

from harness.cli import main
from harness.runner.results import load_results
from harness.runner.suites import SCENES_ROOT, episodes_suite_name, get_suite

SCENE = SCENES_ROOT / "tabletop-v2" / "tabletop-v2-300005.json"


def _write_episodes(folder, lines=None):
    """folder/scenes/kitchen-table.json (a copy of a shipped v2 tabletop) and folder/eps.jsonl
    with two pushes on it."""
    (folder / "scenes").mkdir(parents=True, exist_ok=True)
    shutil.copy(SCENE, folder / "scenes" / "kitchen-table.json")
    header = {"format": "cf-episodes", "version": 2, "task": "tabletop_rearrange", "generator_seed": None}
    eps = lines or [
        {"episode_id": f"mine-{i}", "scene": "kitchen-table.json", "scene_seed": 300005, "instruction": f"push {d} to the {side} of the line",
         "goals": [{"object_id": obj, "side": side, "description": d, "description_kind": "name"}], "start_pose": None,
         "max_steps": 6, "description_kind": "name"}
        for i, (obj, side, d) in enumerate([("obj1", "right", "the orange"), ("obj2", "left", "the tray")])]
    path = folder / "eps.jsonl"
    path.write_text("\n".join(json.dumps(x) for x in [header, *eps]) + "\n")
    return path


def test_own_episodes_on_own_scenes_run_and_resume(tmp_path, capsys):
    eps = _write_episodes(tmp_path)
    suite = get_suite(episodes_suite_name(eps, tmp_path / "scenes"))
    assert suite.task == "tabletop_rearrange" and suite.agents == get_suite("rearrange-v2").agents
    assert suite.limit is None and not suite.lower_bounds and suite.env_kwargs["scenes_root"] == str((tmp_path / "scenes").resolve())
    out = tmp_path / "run"
    args = ["run", "--episodes", str(eps), "--scenes", str(tmp_path / "scenes"), "--agent", "random-pusher", "--backend",
            "serial", "--out", str(out), "--no-report", "--record", "none"]
    assert main(args) == 0, capsys.readouterr().err
    records = load_results(out / "results.jsonl")
    assert sorted(r["episode_id"] for r in records) == ["mine-0", "mine-1"]
    assert {r["suite"] for r in records} == {episodes_suite_name(eps, tmp_path / "scenes")}
    assert all(r["status"] == "ok" and r["extras"]["scene"] for r in records)
    # resume with the stored settings: nothing left to do, the same two records
    assert main(["run", "--out", str(out), "--resume", "--backend", "serial", "--no-report"]) == 0
    assert len(load_results(out / "results.jsonl")) == 2


@pytest.mark.parametrize("damage, match", [
    (lambda e: e.update(scene="kitchen.json"), r"eps.jsonl:line 2: episode 'mine-0': field 'scene'.*kitchen.json"),
    (lambda e: e["goals"][0].update(object_id="obj99"), r"eps.jsonl:line 2: episode 'mine-0' names object 'obj99'"),
    (lambda e: e.update(max_steps=0), r"eps.jsonl:line 2"),
])
def test_a_bad_episode_file_is_refused_before_anything_runs(tmp_path, capsys, damage, match):
    eps = _write_episodes(tmp_path)
    lines = [json.loads(x) for x in eps.read_text().splitlines()[1:]]
    damage(lines[0])
    _write_episodes(tmp_path, lines)
    out = tmp_path / "run"
    code = main(["run", "--episodes", str(eps), "--scenes", str(tmp_path / "scenes"), "--out", str(out), "--backend", "serial"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("cfharness run: --episodes: ")
    assert re.search(match, err), err
    assert not (out / "results.jsonl").exists()


def test_scenes_without_episodes_and_a_missing_scene_folder_are_refused(tmp_path, capsys):
    assert main(["run", "--scenes", str(tmp_path), "--out", str(tmp_path / "r")]) == 2
    assert "--scenes" in capsys.readouterr().err
    eps = _write_episodes(tmp_path)
    assert main(["run", "--episodes", str(eps), "--scenes", str(tmp_path / "nowhere"), "--out", str(tmp_path / "r")]) == 2
    assert "expected a folder of scene files" in capsys.readouterr().err
