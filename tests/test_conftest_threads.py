"""The test workers share the cores: under pytest-xdist each worker's thread pools are sized to
its share (tests/conftest.py), set before numpy loads, so they take effect."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

CONFTEST = Path(__file__).resolve().parent / "conftest.py"
NAMES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "CF_THREADS")
PROBE = (
    "import json, os, runpy, sys\n"
    f"runpy.run_path({str(CONFTEST)!r})\n"
    "import numpy, threadpoolctl\n"
    "blas = sorted({i['num_threads'] for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas'})\n"
    f"print(json.dumps({{'blas': blas, **{{k: os.environ.get(k) for k in {NAMES!r}}}}}))\n"
)


def _probe(**env):
    base = {k: v for k, v in os.environ.items() if k not in NAMES and not k.startswith("PYTEST_XDIST")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**base, **env}, capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs two cores to tell one thread per worker from one per core")
def test_xdist_workers_get_their_share_of_the_cores():
    cores = os.cpu_count()
    shared = _probe(PYTEST_XDIST_WORKER_COUNT=str(cores))
    assert all(shared[k] == "1" for k in NAMES) and shared["blas"] == [1]
    alone = _probe()  # one process (-n 0): the libraries' own defaults
    assert all(alone[k] is None for k in NAMES) and alone["blas"][0] > 1
    mine = _probe(PYTEST_XDIST_WORKER_COUNT=str(cores), OPENBLAS_NUM_THREADS="2")  # a set variable wins
    assert mine["OPENBLAS_NUM_THREADS"] == "2" and mine["blas"] == [2] and mine["CF_THREADS"] == "1"
