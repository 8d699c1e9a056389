"""Bad run settings are refused before the first episode (issue 13), workers die with their
parent, and the serial backend honours timeouts and records an agent's ``SystemExit``.

Settings are checked by :class:`~harness.runner.run.RunConfig` (a ``HarnessError`` naming the
flag, what was expected, what arrived and the nearest names); ``cfharness run`` turns them into
exit status 2, one line on stderr, and nothing written to ``--out``."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conceptfusion.errors import HarnessError
from harness.cli import main
from harness.runner.results import RUN_CONFIG_FILE
from harness.runner.run import RunConfig, episode_jobs, plan_run, run_suites
from harness.runner.suites import get_suite

REPO = Path(__file__).resolve().parents[2]

RUN = ("regression-rearrange",)


def _cli(capsys, tmp_path, *args) -> tuple[int, str, Path]:
    """Run ``cfharness run ARGS --out OUT`` here; (exit status, stderr, OUT)."""
    out = tmp_path / "out"
    rc = main(["run", *args, "--out", str(out), "--no-report"])
    return rc, capsys.readouterr().err, out


# -- every setting is checked, with the flag, what was expected, what arrived, nearest names ----

@pytest.mark.parametrize("kwargs, match", [
    ({"encoder": "embeded"}, r"^--encoder: unknown encoder 'embeded'; did you mean 'embedded', 'embedded-v2'\?"),
    ({"seed": -1}, r"^--seed: expected an integer >= 0 \(the episode seed\), got -1$"),
    ({"seed": "abc"}, r"^--seed: expected an integer >= 0 .*got 'abc'$"),
    ({"seed": True}, r"^--seed: expected an integer >= 0 .*got bool True$"),
    ({"seeds": 0}, r"^--seeds: expected an integer >= 1 \(seeds per episode\), got 0$"),
    ({"seeds": "three"}, r"^--seeds: expected an integer >= 1 .*got 'three'$"),
    ({"seeds": 1.5}, r"^--seeds: expected an integer >= 1 .*got float 1.5$"),
    ({"limit": -148}, r"^--limit: expected an integer >= 1 \(episodes or scenes per suite\), got -148$"),
    ({"limit": 0}, r"^--limit: expected an integer >= 1 .*got 0$"),
    ({"limit": 2.5}, r"^--limit: expected an integer >= 1 .*got float 2.5$"),
    ({"workers": 0}, r"^--workers: expected an integer >= 1 \(worker processes\), got 0$"),
    ({"timeout_s": 0}, r"^--timeout: expected a number of seconds > 0, got 0$"),
    ({"timeout_s": -3.0}, r"^--timeout: expected a number of seconds > 0, got -3.0$"),
    ({"timeout_s": float("nan")}, r"^--timeout: expected a number of seconds > 0, got nan$"),
    ({"timeout_s": "soon"}, r"^--timeout: expected a number of seconds > 0, got 'soon'$"),
    ({"memory_limit_mb": 0}, r"^--memory-limit-mb: expected an integer >= 1 \(MiB of memory per episode worker\), got 0$"),
    ({"memory_limit_mb": "lots"}, r"^--memory-limit-mb: expected an integer >= 1 .*got 'lots'$"),
    ({"memory_limit_mb": 200, "backend": "serial"}, r"^--memory-limit-mb: only for --backend process .*got --backend serial: "
                                                    r"the serial backend runs episodes in this process"),
    ({"backend": "rey"}, r"^--backend: expected one of process, serial, ray, got 'rey'; did you mean 'ray'\?$"),
    ({"address": "127.0.0.1:6379"}, r"^--address: only for --backend ray"),
    ({"backend": "ray", "address": "host:port"}, r"^--address: expected 'auto', 'HOST:PORT' or 'ray://HOST:PORT', got 'host:port'$"),
    ({"suites": ("serch",)}, r"^--suite: unknown suite 'serch'; did you mean 'search'"),
    ({"suites": ()}, r"^--suite: expected at least one suite \(suites: rearrange, rearrange-v2, search, search-v2"),
    ({"suites": RUN * 2}, r"^--suite: each name once, got 'regression-rearrange' more than once$"),
    ({"agents": ("map-puser",)}, r"^--agent: unknown agent 'map-puser'; did you mean 'map-pusher'"),
    ({"agents": ("map-navigator",)}, r"^--agent: agent 'map-navigator' solves object_search, not suite 'regression-rearrange'.*"
                                     r"agents for it: frame-pusher, map-pusher"),
    ({"suites": ("query",), "agents": ("map-pusher",)}, r"^--agent: the map suites \(query\) run no agents"),
    ({"agents": ("no_such_module_here:Agent",)}, r"^--agent: agent import path .*cannot import 'no_such_module_here'"),
    ({"plugins": ("no_such_plugin_here",)}, r"^--import 'no_such_plugin_here': cannot import 'no_such_plugin_here'"),
])
def test_a_bad_setting_is_refused_naming_it(kwargs, match):
    with pytest.raises(HarnessError, match=match):
        RunConfig(**{"suites": RUN, **kwargs})


@pytest.mark.parametrize("options, match", [
    ({"max_pushes": "-5"}, r"^--agent-option max_pushes=-5: agent 'random-pusher' option 'max_pushes': expected an integer >= 1, got '-5'$"),
    ({"max_pushes": "many"}, r"^--agent-option max_pushes=many: .*expected int, got 'many'$"),
    ({"seed": "-1"}, r"^--agent-option seed=-1: agent 'random-pusher' option 'seed': expected an integer >= 0"),
    ({"scan": "maybe"}, r"^--agent-option scan=maybe: agent 'map-pusher' option 'scan': expected a boolean"),
    ({"proposer": "rgdb"}, r"^--agent-option proposer=rgdb: agent 'map-pusher' option 'proposer': unknown mask proposer 'rgdb'; "
                           r"did you mean 'rgbd'\?"),
    ({"bogus": "1"}, r"^--agent-option bogus: no agent or suite of this run takes it \(options of this run: assume_present, identify, "
                     r"max_pushes, name_only_fallback, proposer, scan, seed\)$"),
    ({"max_pushe": "3"}, r"^--agent-option max_pushe: no agent or suite of this run takes it; did you mean 'max_pushes'\?"),
    ({"encoder": "oracle"}, r"^--agent-option encoder=oracle: the encoder is a run setting; give it with --encoder$"),
])
def test_agent_options_need_a_taker_and_a_value_in_range(options, match):
    with pytest.raises(HarnessError, match=match):
        RunConfig(suites=RUN, agent_kwargs=options)


@pytest.mark.parametrize("suites, options, match", [
    (("search",), {"integrate_every": "0"}, r"^--agent-option integrate_every=0: .*expected an integer >= 1, got '0'$"),
    (("search",), {"proposer": "rgbd:fine=3"}, r"^--agent-option proposer=rgbd:fine=3: agent 'map-navigator' option 'proposer': "
                                               r"proposer 'rgbd': 'fine' is not a setting; expected one of .*fine_scale, fixed_size_pixels"),
    (("search",), {"proposer": "rgbd:fixed_size_pixels=-3"}, r"fixed_size_pixels: expected an integer pixel count >= 0 \(0: off\), got -3"),
    (("search",), {"p_stop": "1.5"}, r"^--agent-option p_stop=1.5: .*expected a number in \[0.0, 1.0\], got '1.5'$"),
    (("search",), {"p_stop": "nan"}, r"^--agent-option p_stop=nan: .*got 'nan'$"),
    (("query",), {"frames": "0"}, r"^--agent-option frames=0: suite option 'frames': expected an integer >= 1, got '0'$"),
    (("query",), {"width": "wide"}, r"^--agent-option width=wide: suite option 'width': expected int, got 'wide'$"),
    (("query",), {"proposer": "gt"}, r"^--agent-option proposer: no agent or suite of this run takes it "
                                     r"\(options of this run: frames, height, width\)$"),
    (("ablation",), {"proposer": "sma"}, r"^--agent-option proposer=sma: .*unknown mask proposer 'sma'; did you mean 'sam'\?"),
])
def test_options_of_other_agents_and_of_the_map_suites(suites, options, match):
    with pytest.raises(HarnessError, match=match):
        RunConfig(suites=suites, agent_kwargs=options)


def test_good_settings_pass_and_are_normalised():
    cfg = RunConfig(suites=("query", "search"), agent_kwargs={"frames": "6", "integrate_every": "3"}, limit="2", seed="7",
                    workers="3", timeout_s="1.5")
    assert (cfg.limit, cfg.seed, cfg.workers, cfg.timeout_s) == (2, 7, 3, 1.5)
    assert cfg.agent_kwargs == {"frames": "6", "integrate_every": "3"}  # stored as given: records keep their keys
    assert RunConfig(suites=("ablation",), agent_kwargs={"proposer": "gt"}).agent_kwargs == {"proposer": "gt"}


USER_AGENT = '''
class Fast:
    privileged = False

    def __init__(self, speed=1.0):
        self.speed = speed

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return None
'''


def test_a_user_agent_takes_the_options_its_signature_names(tmp_path, monkeypatch):
    (tmp_path / "cf_bad_input_fast.py").write_text(USER_AGENT)
    monkeypatch.syspath_prepend(str(tmp_path))
    agents = ("cf_bad_input_fast:Fast", "random-pusher")
    cfg = RunConfig(suites=RUN, agents=agents, agent_kwargs={"speed": "2", "max_pushes": "3"}, limit=1)
    jobs = {j.agent: j.agent_kwargs for j in episode_jobs(get_suite(RUN[0]), cfg, "r")}
    assert jobs == {"cf_bad_input_fast:Fast": {"speed": "2"}, "random-pusher": {"max_pushes": "3"}}
    with pytest.raises(HarnessError, match=r"^--agent-option sped: no agent .*; did you mean 'speed', 'seed'\? "
                                           r"\(options of this run: max_pushes, seed, speed\)$"):
        RunConfig(suites=RUN, agents=agents, agent_kwargs={"sped": "2"})


# -- the command line: exit 2, one line on stderr, nothing written ----------------------------

@pytest.mark.parametrize("args, line", [
    (["--encoder", "embeded"], "cfharness run: --encoder: unknown encoder 'embeded'; did you mean 'embedded', 'embedded-v2'?"),
    (["--agent-option", "max_pushes=-5"], "cfharness run: --agent-option max_pushes=-5: agent 'random-pusher' option "
                                          "'max_pushes': expected an integer >= 1, got '-5'"),
    (["--agent-option", "bogus=1"], "cfharness run: --agent-option bogus: no agent or suite of this run takes it"),
    (["--agent-option", "bogus"], "cfharness run: --agent-option: expected KEY=VALUE, got 'bogus'"),
    (["--agent-option", "seed=1", "--agent-option", "seed=2"], "cfharness run: --agent-option seed: given twice, '1' and '2'"),
    (["--seed", "-1"], "cfharness run: --seed: expected an integer >= 0 (the episode seed), got '-1'"),
    (["--seed", "x"], "cfharness run: --seed: expected an integer >= 0 (the episode seed), got 'x'"),
    (["--limit", "-148"], "cfharness run: --limit: expected an integer >= 1 (episodes or scenes per suite), got '-148'"),
    (["--limit", "0"], "cfharness run: --limit: expected an integer >= 1 (episodes or scenes per suite), got '0'"),
    (["--limit", "ten"], "cfharness run: --limit: expected an integer >= 1 (episodes or scenes per suite), got 'ten'"),
    (["--workers", "0"], "cfharness run: --workers: expected an integer >= 1 (worker processes), got '0'"),
    (["--timeout", "0"], "cfharness run: --timeout: expected a number of seconds > 0, got '0'"),
    (["--timeout", "soon"], "cfharness run: --timeout: expected a number of seconds > 0, got 'soon'"),
    (["--memory-limit-mb", "0"], "cfharness run: --memory-limit-mb: expected an integer >= 1 (MiB of memory per episode "
                                 "worker), got '0'"),
    (["--memory-limit-mb", "200", "--backend", "serial"], "cfharness run: --memory-limit-mb: only for --backend process (each "
     "episode's worker process is watched and stopped past the limit), got --backend serial: the serial backend runs episodes "
     "in this process, which it cannot stop without ending the run"),
    (["--backend", "rey"], "cfharness run: --backend: expected one of process, serial, ray, got 'rey'; did you mean 'ray'?"),
    (["--suite", "serch"], "cfharness run: --suite: unknown suite 'serch'; did you mean 'search'"),
    (["--agent", "map-puser"], "cfharness run: --agent: unknown agent 'map-puser'; did you mean 'map-pusher'"),
    (["--agent", "map-navigator"], "cfharness run: --agent: agent 'map-navigator' solves object_search, not suite"),
    (["--limti", "5"], "cfharness run: unrecognized arguments: --limti 5; did you mean '--limit'"),
    (["--limit"], "cfharness run: argument --limit: expected one argument (see cfharness run --help)"),
])
def test_the_command_exits_2_with_one_line_and_writes_nothing(capsys, tmp_path, args, line):
    suite = [] if "--suite" in args else ["--suite", RUN[0]]
    try:
        rc = main(["run", *suite, *args, "--out", str(tmp_path / "out"), "--no-report"])
    except SystemExit as exc:  # argparse's own errors
        rc = exc.code
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith(line), err
    assert not (tmp_path / "out").exists()


def test_an_unreachable_ray_address_fails_fast_and_writes_nothing(capsys, tmp_path):
    t0 = time.monotonic()
    rc, err, out = _cli(capsys, tmp_path, "--suite", RUN[0], "--backend", "ray", "--address", "127.0.0.1:1")
    assert rc == 2 and time.monotonic() - t0 < 30
    assert err.count("\n") == 1
    assert (err.startswith("cfharness run: --address 127.0.0.1:1: cannot reach a Ray cluster at 127.0.0.1:1 within 5 s")
            or 'the ray backend needs Ray: pip install -e ".[ray]"' in err), err
    assert not out.exists()


def test_a_start_that_failed_does_not_refuse_the_same_command(tmp_path):
    config = RunConfig(suites=RUN, agents=("random-pusher",), limit=1, backend="serial")
    first = plan_run(config, tmp_path)  # writes run.json; then the run dies before its first record
    assert (tmp_path / RUN_CONFIG_FILE).exists() and not first.results.exists()
    again = plan_run(config, tmp_path)  # the same command again: a fresh run, not "other settings"
    assert again.run_id != first.run_id and len(again.todo) == 1
    other = RunConfig(suites=RUN, agents=("random-pusher",), limit=2, backend="serial")
    assert len(plan_run(other, tmp_path).todo) == 2  # no results yet, so other settings may start afresh too


def test_a_failed_ray_start_leaves_no_run_json(tmp_path):
    pytest.importorskip("ray", reason="the ray extra")
    from harness.runner.backends import RayUnavailableError

    config = RunConfig(suites=RUN, agents=("random-pusher",), limit=1, backend="ray", address="127.0.0.1:1")
    with pytest.raises(RayUnavailableError, match=r"cannot reach a Ray cluster at 127\.0\.0\.1:1 within 5 s"):
        plan_run(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()


# -- processes: workers die with their parent ----------------------------------------------------

SLEEPER = '''
import os
import time
from pathlib import Path


class Sleeper:
    """Marks that its worker runs a job, then sleeps through it."""

    privileged = False

    def __init__(self):
        Path(os.environ["CF_SLEEPER_DIR"], f"started-{os.getpid()}").touch()
        time.sleep(float(os.environ.get("CF_SLEEP_S", "120")))

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return None
'''


def _descendants(root: int) -> dict[int, str]:
    """pid -> command line of every process below ``root`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        children.setdefault(int(text[text.rindex(")") + 2:].split()[1]), []).append(int(stat.parent.name))
    out, todo = {}, [root]
    while todo:
        for pid in children.get(todo.pop(), []):
            try:
                out[pid] = Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")
            except OSError:
                continue
            todo.append(pid)
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")  # a zombie has exited (nobody reaped it yet)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc")
def test_workers_and_the_resource_tracker_die_with_a_killed_parent(tmp_path):
    (tmp_path / "cf_bad_input_sleeper.py").write_text(SLEEPER)
    marks = tmp_path / "marks"
    marks.mkdir()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
           "CF_SLEEPER_DIR": str(marks), "MUJOCO_GL": "egl"}
    run = subprocess.Popen(
        [sys.executable, "-m", "harness.cli", "run", "--suite", RUN[0], "--agent", "cf_bad_input_sleeper:Sleeper", "--limit", "2",
         "--workers", "2", "--out", str(tmp_path / "out"), "--no-report"],
        cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    survivors: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while len(list(marks.iterdir())) < 2 and time.monotonic() < deadline and run.poll() is None:
            time.sleep(0.05)
        below = _descendants(run.pid)
        assert len(list(marks.iterdir())) == 2, "the workers did not start their jobs"
        # the fork server and the two workers forked from it (all three run its command line)
        assert sum("multiprocessing.forkserver" in c for c in below.values()) == 3, below
        assert any("resource_tracker" in c for c in below.values()), below
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(map(_alive, below)):
            time.sleep(0.05)
        survivors = [pid for pid in below if _alive(pid)]
        assert not survivors, {pid: below[pid] for pid in survivors}
    finally:
        if run.poll() is None:
            run.kill()
        for pid in survivors:  # clean up what this test started
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass


# -- the serial backend: timeouts and SystemExit --------------------------------------------------

EXITER = '''
import sys


class ExitsAtOnce:
    """Calls sys.exit(3) while it is built."""

    privileged = False

    def __init__(self):
        sys.exit(3)

    def reset(self, seed=None):
        pass

    def act(self, observation, info=None):
        return None
'''


def test_the_serial_backend_honours_the_timeout(tmp_path, monkeypatch):
    (tmp_path / "cf_bad_input_sleeper.py").write_text(SLEEPER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("CF_SLEEPER_DIR", str(tmp_path))
    monkeypatch.setenv("CF_SLEEP_S", "60")
    config = RunConfig(suites=RUN, agents=("cf_bad_input_sleeper:Sleeper",), limit=2, backend="serial", timeout_s=0.3)
    t0 = time.monotonic()
    records = run_suites(config, tmp_path / "run", progress=False)
    assert time.monotonic() - t0 < 20
    assert [r["status"] for r in records] == ["timeout", "timeout"]  # recorded, and the run went on
    assert all("exceeded 0.3 s" in r["error"] and r["timings"]["wall_s"] < 5 for r in records)
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


@pytest.mark.parametrize("backend", ["serial", "process"])
def test_an_agent_calling_sys_exit_is_recorded_as_failed(tmp_path, monkeypatch, backend):
    (tmp_path / "cf_bad_input_exiter.py").write_text(EXITER)
    monkeypatch.syspath_prepend(str(tmp_path))
    config = RunConfig(suites=RUN, agents=("cf_bad_input_exiter:ExitsAtOnce",), limit=2, backend=backend, workers=1)
    records = run_suites(config, tmp_path / "run", progress=False)
    assert [r["status"] for r in records] == ["failed", "failed"]
    assert all(r["error"].startswith("SystemExit: the episode called sys.exit(3); recorded as failed") for r in records)
