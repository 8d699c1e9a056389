"""Everything ``cfharness run`` can check before the first episode is checked then (issue 41):
encoder weights that are not there, an import path that names no agent, option values numpy
cannot hold, an ``--import`` module that raises or exits, an ``--out`` that cannot be a run
folder. Each is exit status 2, one line on stderr naming what was expected and what arrived,
no traceback, and nothing written to ``--out``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from harness.cli import main

RUN = ["--suite", "rearrange", "--agent", "random-pusher", "--limit", "1", "--backend", "serial", "--no-report"]


def _refused(capsys, args: list[str], out: Path) -> str:
    """Run ``cfharness run RUN ARGS --out OUT`` here; its one stderr line, once it exited 2 without a traceback."""
    rc = main(["run", *RUN, *args, "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.strip()


@pytest.mark.parametrize("args, line", [
    (["--encoder", "hf:nonexistent/model"],
     "cfharness run: --encoder: hf:nonexistent/model: expected a model in the local Hugging Face cache ("),
    (["--encoder", "onnx:/nonexistent"],
     "cfharness run: --encoder: /nonexistent: no such folder; expected an ONNX CLIP folder with image.onnx, text.onnx"),
    (["--encoder", "embedded:/nonexistent"],
     "cfharness run: --encoder: embedded:/nonexistent: expected a folder of embedded weights, no folder is there"),
    (["--agent", "os:getcwd"], "cfharness run: --agent os:getcwd: expected an agent class with reset() and act(), or a "
                               "function that builds one, got built-in function posix.getcwd"),
    (["--agent", "os:sep"], "cfharness run: --agent os:sep: expected an agent class with reset() and act(), or a function "
                            "that builds one, got str '/'"),
    (["--agent", "pathlib:Path"], "cfharness run: --agent pathlib:Path: expected an agent class with reset() and act(), or a "
                                  "function that builds one, got class pathlib.Path without reset() and act()"),
    (["--agent", "json:loads"], "cfharness run: --agent json:loads: expected an agent class with reset() and act(), or a "
                                "function that builds one from the keywords the run passes (encoder), but function "
                                "json.loads(s, *"),
    (["--agent-option", f"max_pushes={10**20}"],
     f"cfharness run: --agent-option max_pushes={10**20}: agent 'random-pusher' option 'max_pushes': expected an integer "
     f">= 1 that fits in 64 bits (at most {2**63 - 1}), got '{10**20}'"),
])
def test_what_no_episode_could_use_is_refused_before_the_first(capsys, tmp_path, args, line):
    out = tmp_path / "out"
    assert _refused(capsys, args, out).startswith(line)
    assert not out.exists()


def test_the_largest_int64_option_runs(tmp_path):
    """The 64-bit bound is numpy's: the random pusher draws its push count up to it."""
    from harness.runner.results import load_results

    assert main(["run", *RUN, "--agent-option", f"max_pushes={2**63 - 1}", "--out", str(tmp_path / "out")]) == 0
    [record] = load_results(tmp_path / "out" / "results.jsonl")
    assert record["status"] == "ok", record["error"]


PLUGINS = {
    "cf_raises_on_import": "raise RuntimeError('no licence server')\n",
    "cf_exits_on_import": "import sys\nsys.exit(3)\n",
}


@pytest.mark.parametrize("module, line", [
    ("cf_raises_on_import", "cfharness run: --import 'cf_raises_on_import': expected a module that imports cleanly (it "
                            "registers agents or encoders), but importing 'cf_raises_on_import' raised RuntimeError: no licence server"),
    ("cf_exits_on_import", "cfharness run: --import 'cf_exits_on_import': expected a module that imports cleanly (it "
                           "registers agents or encoders), but importing 'cf_exits_on_import' called sys.exit(3)"),
])
def test_an_import_that_raises_or_exits_is_one_line(capsys, tmp_path, monkeypatch, module, line):
    (tmp_path / f"{module}.py").write_text(PLUGINS[module])
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    assert _refused(capsys, ["--import", module], out) == line
    assert not out.exists()


def test_an_agent_module_that_raises_on_import_is_one_line(capsys, tmp_path, monkeypatch):
    (tmp_path / "cf_raises_on_import.py").write_text(PLUGINS["cf_raises_on_import"])
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _refused(capsys, ["--agent", "cf_raises_on_import:Agent"], tmp_path / "out") == (
        "cfharness run: --agent: agent import path 'cf_raises_on_import:Agent': expected a module that imports cleanly, "
        "but importing 'cf_raises_on_import' raised RuntimeError: no licence server")


def test_an_out_that_cannot_be_a_run_folder_is_one_line(capsys, tmp_path):
    assert _refused(capsys, [], "") == "cfharness run: --out: expected a folder path, got ''"
    a_file = tmp_path / "notes.txt"
    a_file.write_text("not a folder")
    assert _refused(capsys, [], a_file) == f"cfharness run: --out {a_file}: expected a folder, got a file"
    assert _refused(capsys, [], a_file / "sub") == (f"cfharness run: --out {a_file / 'sub'}: expected a folder path, but "
                                                    f"{a_file} is a file, so no folder can be made there")
    assert a_file.read_text() == "not a folder"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder (os.access says so too)")
def test_a_read_only_out_is_one_line(capsys, tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        assert _refused(capsys, [], locked / "run") == (f"cfharness run: --out {locked / 'run'}: expected a folder this user "
                                                        f"can write in, but {locked}, where it would be made, is not writable")
        assert _refused(capsys, [], locked) == (f"cfharness run: --out {locked}: expected a folder this user can write in, "
                                                "but this folder is not writable")
    finally:
        locked.chmod(0o700)


@pytest.mark.parametrize("options, line", [
    (["planner_url=ftp://example/v1"], "cfharness run: --agent-option planner=chat: "),
    (["planner_url=http://127.0.0.1:9/v1", "planner_model=m"], "cfharness run: --agent-option planner=chat: "),
])
def test_a_chat_planner_server_is_checked_before_any_episode(capsys, tmp_path, options, line):
    """A bad URL, or a server that is not there (port 9, discard), stops the run before the first episode."""
    args = ["--suite", "instruct-v2", "--agent", "map-planner", "--limit", "1", "--backend", "serial", "--no-report",
            "--agent-option", "planner=chat", *[a for o in options for a in ("--agent-option", o)]]
    rc = main(["run", *args, "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith(line) and "Traceback" not in err, err
    assert not (tmp_path / "run").exists()
