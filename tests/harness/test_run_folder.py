"""A run folder is owned by one run at a time (issue 41): a second run on a held folder is
refused at once with exit status 2 naming the holder, and a lock file left by a dead process
does not block."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from harness.cli import main
from harness.runner.folder import LOCK_FILE, RunFolderBusyError, lock_run_folder, refuse_if_busy
from harness.runner.results import load_results
from harness.runner.run import RunConfig, plan_run

REPO = Path(__file__).resolve().parents[2]

RUN = ["--suite", "rearrange", "--agent", "random-pusher", "--limit", "1", "--backend", "serial", "--no-report"]

HOLDER = """
import sys
from harness.runner.folder import lock_run_folder

lock = lock_run_folder(sys.argv[1], "holder-run")
print("locked", flush=True)
sys.stdin.read()  # hold the folder until the test closes our stdin
"""


def _holder(run_dir: Path) -> subprocess.Popen:
    """Another process holding ``run_dir`` the way a run does, until its stdin is closed."""
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(run_dir)], cwd=REPO, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


def test_a_second_run_on_a_held_folder_exits_2_naming_the_holder_then_runs_once_it_is_free(tmp_path, capsys):
    out = tmp_path / "run"
    holder = _holder(out)
    try:
        for extra in ([], ["--resume"]):
            rc = main(["run", *RUN, "--out", str(out), *extra])
            err = capsys.readouterr().err
            assert rc == 2, err
            assert err.count("\n") == 1 and "Traceback" not in err, err
            assert err.startswith(f"cfharness run: --out {out}: expected a run folder no other run is using, but another "
                                  f"cfharness run holds it (pid {holder.pid} on host {socket.gethostname()}, run id holder-run, "
                                  "started 20"), err
        assert sorted(p.name for p in out.iterdir()) == [LOCK_FILE]  # nothing of the refused runs was written
    finally:
        holder.stdin.close()
        holder.wait(timeout=60)
    assert main(["run", *RUN, "--out", str(out)]) == 0
    assert len(load_results(out / "results.jsonl")) == 1
    assert json.loads((out / LOCK_FILE).read_text())["pid"] == os.getpid()  # the last holder is named


def test_a_lock_file_left_by_a_killed_run_does_not_block(tmp_path):
    out = tmp_path / "run"
    holder = _holder(out)
    holder.send_signal(signal.SIGKILL)  # dies holding the lock: the OS drops it, the file stays
    holder.wait(timeout=60)
    holder.stdout.close()
    holder.stdin.close()
    assert json.loads((out / LOCK_FILE).read_text())["pid"] == holder.pid
    refuse_if_busy(out)  # the file's content alone does not block
    plan = plan_run(RunConfig(suites=("rearrange",), agents=("random-pusher",), limit=1, backend="serial"), out)
    try:
        info = json.loads((out / LOCK_FILE).read_text())
        assert (info["pid"], info["run_id"]) == (os.getpid(), plan.run_id)
    finally:
        plan.close()


def test_one_process_shares_its_hold_and_frees_the_folder_when_every_hold_is_released(tmp_path):
    probe = [sys.executable, "-c", "import sys; from harness.runner.folder import refuse_if_busy; refuse_if_busy(sys.argv[1])",
             str(tmp_path)]
    first = lock_run_folder(tmp_path, "a")
    second = lock_run_folder(tmp_path, "b")  # the same process planning the folder again (resume after a plan)
    first.release()
    busy = subprocess.run(probe, cwd=REPO, capture_output=True, text=True)
    assert busy.returncode != 0 and "RunFolderBusyError" in busy.stderr and "run id b" in busy.stderr
    second.release()
    second.release()  # idempotent
    free = subprocess.run(probe, cwd=REPO, capture_output=True, text=True)
    assert free.returncode == 0, free.stderr


def test_a_folder_held_elsewhere_is_refused_by_the_library_too(tmp_path):
    holder = _holder(tmp_path)
    try:
        with pytest.raises(RunFolderBusyError, match=rf"holds it \(pid {holder.pid} on host .*, run id holder-run"):
            lock_run_folder(tmp_path, "mine")
    finally:
        holder.stdin.close()
        holder.wait(timeout=60)
    lock_run_folder(tmp_path, "mine").release()
