"""Shared pytest set-up: headless rendering for every test that touches a simulator."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def _share_the_cores() -> None:
    """Under pytest-xdist, each worker's thread pools (OpenBLAS, OpenMP for torch, MKL and the
    encoders' onnxruntime sessions, ``CF_THREADS``) get its share of the cores instead of one
    thread per core each. With a pool per core in every worker, the pools' idle threads spin
    while the other workers' threads want the same cores: on two cores the tests outside the gate
    took 190 s of CPU with them and 167 s without. Set before numpy or torch load (this file is
    imported first); a variable already set wins, and subprocesses inherit the choice."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 0)
    if workers < 2:
        return
    share = str(max(1, (os.cpu_count() or 1) // workers))
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "CF_THREADS"):
        os.environ.setdefault(name, share)


_share_the_cores()


def pytest_collection_modifyitems(config, items):
    """The regression gate (``gate`` tests: hundreds of episodes on worker processes) runs last.

    With ``-n`` (pytest-xdist, the default in ``pyproject.toml``) the load scheduler hands out the
    quick tests first and the gate tests as workers free up, so each gate test overlaps the others
    instead of queueing behind one long test on one worker."""
    gate = [item for item in items if item.get_closest_marker("gate") is not None]
    if gate:
        rest = [item for item in items if item.get_closest_marker("gate") is None]
        items[:] = rest + gate
