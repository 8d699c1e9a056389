"""A new user's first minutes, timed: the README's quickstart commands, run literally.

    python benchmarks/bench_first_hour.py [--workdir DIR] [--readme README.md]

Reads the first shell block under the README's "Quickstart" heading and runs each line as
written (through ``bash -c``), in order, in a fresh working folder, as a user who just installed
the project would. A command that serves until Ctrl-C (``cfharness view``) is stopped once it
prints the address it serves. Reported: each command's seconds and exit status, the seconds until
the first report exists (``report.html`` of the quickstart's run), and the total. Target: a
first report in under 3 minutes after install.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # this checkout, _machine

REPO = Path(__file__).resolve().parents[1]
_SERVES = ("cfharness view",)


def quickstart_commands(readme: str) -> list[str]:
    """The command lines of the first shell block under the README's "Quickstart" heading, with
    their trailing comments removed."""
    start = re.search(r"^## Quickstart.*$", readme, flags=re.M)
    if start is None:
        raise ValueError("README: expected a '## Quickstart' section")
    block = re.search(r"^```bash\n(.*?)^```", readme[start.end():], flags=re.S | re.M)
    if block is None:
        raise ValueError("README: expected a ```bash block in the Quickstart section")
    lines = [re.sub(r"\s+#.*$", "", ln).strip() for ln in block.group(1).splitlines()]
    return [ln for ln in lines if ln and not ln.startswith("#")]


def _serve_until_ready(cmd: str, cwd: Path, timeout_s: float = 120.0) -> tuple[int, float]:
    """Start a serving command, wait for its "Serving ... at" line, stop it: (0 or its exit status, seconds)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(["bash", "-c", cmd], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        for line in proc.stdout:
            if line.startswith("Serving "):
                return 0, time.perf_counter() - t0
            if time.perf_counter() - t0 > timeout_s:
                break
        return proc.poll() or 1, time.perf_counter() - t0
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workdir", help="working folder (default: a fresh temporary one)")
    p.add_argument("--readme", default=str(REPO / "README.md"))
    args = p.parse_args(argv)
    commands = quickstart_commands(Path(args.readme).read_text())
    work = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="cf-first-hour-"))
    work.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    os.environ.update(env)
    t0 = time.perf_counter()
    first_report = None
    print(f"working folder: {work}")
    for cmd in commands:
        if cmd.startswith(_SERVES):
            code, secs = _serve_until_ready(cmd, work)
        else:
            t = time.perf_counter()
            code = subprocess.run(["bash", "-c", cmd], cwd=work, env=env, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL).returncode
            secs = time.perf_counter() - t
        print(f"{secs:7.1f} s  exit {code}  {cmd}")
        if first_report is None and any(work.glob("runs/*/report/report.html")):
            first_report = time.perf_counter() - t0
        if code != 0:
            print("stopped: the command failed", file=sys.stderr)
            return 1
    total = time.perf_counter() - t0
    print(f"first report after {first_report:.1f} s" if first_report is not None else "no report was written")
    print(f"total {total:.1f} s (target: a first report in under 180 s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
