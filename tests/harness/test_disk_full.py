"""A full disk stops ``cfharness run`` cleanly, and ``--resume`` finishes the run (issue 41).

A run whose folder's file system fills up (ENOSPC), goes over quota (EDQUOT) or turns read-only
(EROFS) ends with exit status 74 (:data:`harness.commands.EXIT_NO_ROOM`) and one line on stderr,
no traceback: what could not be written, how many records are kept, and the command that
finishes the run. The results file keeps whole records only (a record cut short by the full disk
is cut back), and once there is room, ``--resume`` runs every episode without a record, each once.
An ``--out`` on a file system that is read-only from the start is refused before anything runs
(exit status 2).

The disk-full cases mount a small tmpfs (root and ``mount`` needed; skipped with the reason
elsewhere). It is sized in pages of 4 KiB: tmpfs gives a file its space a page at a time, so a
run folder takes one page for its lock file, one for ``run.json`` and the rest for
``results.jsonl`` (a rearrange record is about 550 bytes, some 7 to a page).
"""

from __future__ import annotations

import errno
import json
import os
import shlex
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from harness.cli import main
from harness.commands import EXIT_NO_ROOM
from harness.runner import results as results_module
from harness.runner.folder import RunFolderFullError, writing
from harness.runner.results import append_record, load_results, make_record, record_key, repair_results

REPO = Path(__file__).resolve().parents[2]
PAGE = 4096
"""The page size the tmpfs sizes below are worked out for."""
RUN = ["run", "--suite", "rearrange", "--agent", "random-pusher", "--record", "none", "--backend", "serial"]


def _mount_tmpfs(where: Path, pages: int, *, read_only: bool = False) -> None:
    """Mount a tmpfs of ``pages`` pages at ``where``, or skip the test saying why it cannot."""
    if os.geteuid() != 0:
        pytest.skip("needs a tmpfs mount (root): not running as root")
    if shutil.which("mount") is None or shutil.which("umount") is None:
        pytest.skip("needs a tmpfs mount (root): no mount/umount command")
    if os.sysconf("SC_PAGE_SIZE") != PAGE:
        pytest.skip(f"the tmpfs sizes are worked out for {PAGE}-byte pages, this machine has {os.sysconf('SC_PAGE_SIZE')}")
    where.mkdir(parents=True, exist_ok=True)
    options = f"size={pages * PAGE // 1024}k" + (",ro" if read_only else "")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"needs a tmpfs mount (root): mount -t tmpfs -o {options} failed: {done.stderr.strip() or done.returncode}")


def _grow(where: Path, pages: int) -> None:
    """Make room: remount the tmpfs at ``where`` with ``pages`` pages."""
    subprocess.run(["mount", "-o", f"remount,size={pages * PAGE // 1024}k", str(where)], check=True, capture_output=True)


@pytest.fixture
def disk(tmp_path):
    """A folder to mount a tmpfs on (:func:`_mount_tmpfs`); unmounted afterwards (lazily: a
    process that failed may still hold a file there)."""
    where = tmp_path / "disk"
    yield where
    if os.path.ismount(where):
        subprocess.run(["umount", "-l", str(where)], check=False, capture_output=True)


def _cli(*args: str) -> subprocess.CompletedProcess:
    """``python -m harness.cli ARGS`` in a fresh process (as a user runs it), stdout and stderr captured."""
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "harness.cli", *args], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=600)


def _whole_lines(results: Path) -> list[dict]:
    """Every line of ``results`` parsed as JSON, after checking that the file ends with a newline
    (no half-written last line)."""
    data = results.read_bytes()
    assert data.endswith(b"\n"), f"expected whole lines only, got a file ending with {data[-60:]!r}"
    return [json.loads(line) for line in data.decode("utf-8").splitlines()]


def _no_room_line(out: Path, what: str, filename: Path, reason: str, kept: str, planned: int) -> str:
    """The line ``cfharness run`` ends with when the disk fills up after it started."""
    resume = f"cfharness run --out {shlex.quote(str(out))} --resume"
    return (f"cfharness run: --out {out}: could not write {what} ({filename}): {reason}; {kept} kept in "
            f"{out / 'results.jsonl'} ({planned} planned); free space and finish the run with: {resume}")


def _rec(episode_id: str) -> dict:
    """A results record of ``episode_id`` (the other fields made up)."""
    return make_record(run_id="r1", suite="rearrange", task="tabletop_rearrange", agent="random-pusher", encoder="none",
                       episode_id=episode_id, seed=0, status="ok", metrics={"success": False})


def _half_then_full(real_write):
    """An ``os.write`` that does what a full tmpfs does: writes half of a line, then raises ENOSPC."""
    def write(fd, data):
        if len(data) > 8:
            return real_write(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return write


def _each_once(records: list[dict], planned: int) -> None:
    """Check that ``records`` hold ``planned`` distinct episodes, each once, all of one run."""
    counts = Counter(record_key(r) for r in records)
    assert len(counts) == planned, f"expected {planned} distinct episodes, got {len(counts)}"
    twice = [key for key, n in counts.items() if n > 1]
    assert not twice, f"expected each episode once, got these more than once: {twice}"
    assert len({r["run_id"] for r in records}) == 1


# -- without a mount -------------------------------------------------------------------------------

def test_a_record_cut_short_by_a_full_disk_is_cut_back(tmp_path, monkeypatch):
    path = tmp_path / "results.jsonl"
    append_record(path, _rec("ep-0"))
    before = path.read_bytes()
    monkeypatch.setattr(results_module.os, "write", _half_then_full(os.write))
    with pytest.raises(OSError) as caught:
        append_record(path, _rec("ep-1"))
    assert caught.value.errno == errno.ENOSPC
    assert path.read_bytes() == before  # the partial line is gone
    monkeypatch.undo()
    append_record(path, _rec("ep-1"))
    assert [r["episode_id"] for r in _whole_lines(path)] == ["ep-0", "ep-1"]


def test_a_record_that_cannot_be_cut_back_is_repaired_by_resume(tmp_path, monkeypatch):
    path = tmp_path / "results.jsonl"
    append_record(path, _rec("ep-0"))
    before = path.read_bytes()

    def refuse(fd, size):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(results_module.os, "write", _half_then_full(os.write))
    monkeypatch.setattr(results_module.os, "ftruncate", refuse)
    with pytest.raises(OSError, match="No space left"):
        append_record(path, _rec("ep-1"))
    monkeypatch.undo()
    half = path.read_bytes()
    assert half.startswith(before) and len(half) > len(before) and not half.endswith(b"\n")
    assert repair_results(path) == len(half) - len(before)
    assert path.read_bytes() == before


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT, errno.EROFS])
def test_writing_names_what_a_full_or_read_only_disk_refused(tmp_path, code):
    with pytest.raises(RunFolderFullError) as caught:
        with writing("a results record", tmp_path / "results.jsonl"):
            raise OSError(code, os.strerror(code))
    assert (caught.value.errno, caught.value.what, caught.value.filename) == (code, "a results record",
                                                                             str(tmp_path / "results.jsonl"))
    assert caught.value.strerror == os.strerror(code)


def test_writing_lets_other_errors_through(tmp_path):
    with pytest.raises(PermissionError):
        with writing("run.json", tmp_path / "run.json"):
            raise PermissionError(errno.EACCES, "Permission denied")


def test_a_quota_exceeded_mid_run_stops_it_with_74_and_resume_finishes_it(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    real_append = results_module.append_record
    calls = []

    def over_quota_on_the_third(path, record):
        calls.append(record["episode_id"])
        if len(calls) == 3:
            raise OSError(errno.EDQUOT, os.strerror(errno.EDQUOT))
        real_append(path, record)

    monkeypatch.setattr("harness.runner.run.append_record", over_quota_on_the_third)
    rc = main([*RUN, "--limit", "4", "--no-report", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == EXIT_NO_ROOM, err
    assert "Traceback" not in err, err
    assert err.strip().splitlines()[-1] == _no_room_line(out, "a results record", out / "results.jsonl",
                                                         os.strerror(errno.EDQUOT), "2 finished records", 4), err
    assert len(_whole_lines(out / "results.jsonl")) == 2

    monkeypatch.undo()
    assert main(["run", "--out", str(out), "--resume", "--backend", "serial", "--no-report"]) == 0
    _each_once(load_results(out / "results.jsonl"), 4)


# -- on a small tmpfs --------------------------------------------------------------------------------

def test_a_full_disk_stops_the_run_cleanly_and_resume_finishes_it(disk):
    _mount_tmpfs(disk, 4)  # lock file, run.json and two pages of records: about 15 of the 40
    out = disk / "run"
    done = _cli(*RUN, "--limit", "40", "--no-report", "--out", str(out))
    assert done.returncode == EXIT_NO_ROOM, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    records = _whole_lines(out / "results.jsonl")
    assert 0 < len(records) < 40, f"expected the tmpfs to fill part-way, got {len(records)} of 40 records"
    assert done.stderr.strip().splitlines()[-1] == _no_room_line(
        out, "a results record", out / "results.jsonl", "No space left on device", f"{len(records)} finished records", 40)

    _grow(disk, 256)
    resumed = _cli("run", "--out", str(out), "--resume", "--backend", "serial", "--no-report")
    assert resumed.returncode == 0, resumed.stderr
    final = _whole_lines(out / "results.jsonl")
    assert final[: len(records)] == records  # the kept records stay as they were
    _each_once(final, 40)


def test_a_disk_full_before_the_first_episode_says_nothing_was_run(disk):
    _mount_tmpfs(disk, 1)  # room for the lock file, none for run.json
    out = disk / "run"
    done = _cli(*RUN, "--limit", "1", "--no-report", "--out", str(out))
    assert done.returncode == EXIT_NO_ROOM, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"cfharness run: --out {out}: could not write run.json ({out / 'run.json'}): No space left on device; nothing "
        "was run; free space and run the command again"), done.stderr
    assert sorted(p.name for p in out.iterdir()) == [".cfharness.lock"]  # no temporary file left behind

    _grow(disk, 64)
    again = _cli(*RUN, "--limit", "1", "--no-report", "--out", str(out))
    assert again.returncode == 0, again.stderr
    _each_once(_whole_lines(out / "results.jsonl"), 1)


def test_a_full_disk_while_writing_the_report_keeps_every_record_and_resume_writes_it(disk):
    _mount_tmpfs(disk, 4)  # the records take one page; the report's figures do not fit in the last
    out = disk / "run"
    done = _cli(*RUN, "--limit", "3", "--out", str(out))
    assert done.returncode == EXIT_NO_ROOM, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().splitlines()[-1] == _no_room_line(
        out, "the report", out / "report", "No space left on device", "3 finished records", 3), done.stderr
    assert len(_whole_lines(out / "results.jsonl")) == 3

    _grow(disk, 1024)
    resumed = _cli("run", "--out", str(out), "--resume", "--backend", "serial")
    assert resumed.returncode == 0, resumed.stderr
    assert (out / "report" / "report.md").is_file() and (out / "report" / "report.html").is_file()
    _each_once(_whole_lines(out / "results.jsonl"), 3)


def test_an_out_on_a_read_only_file_system_is_refused_before_starting(disk, capsys):
    _mount_tmpfs(disk, 4, read_only=True)
    for out, where in ((disk, "this folder"), (disk / "run", f"{disk}, where it would be made,")):
        rc = main([*RUN, "--limit", "1", "--no-report", "--out", str(out)])
        err = capsys.readouterr().err
        assert rc == 2, err
        assert err == (f"cfharness run: --out {out}: expected a folder this user can write in, but {where} is not "
                       "writable (a read-only file system)\n")
    assert list(disk.iterdir()) == []
