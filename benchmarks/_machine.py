"""How fast this machine is right now: a line every benchmark prints before its figures.

The same code runs up to twice as fast on one day as on another on the shared 2-core machine
(every benchmark and the default comparison move together), so published figures carry the
probe they were measured with:

    python benchmarks/_machine.py

* load average (other work on the cores);
* memory read bandwidth: the best of 5 sums of a 200 MB float32 array (GB/s);
* one core's arithmetic: the best of 5 products of two 512x512 float64 matrices on one BLAS
  thread (ms).
"""

from __future__ import annotations

import os
import time

import numpy as np

__all__ = ["probe", "probe_line"]


def probe() -> dict:
    """``{"load": 1-minute load average, "cores": n, "read_gb_s": ..., "matmul_ms": ...}``."""
    from threadpoolctl import threadpool_limits

    a = np.ones(50_000_000, np.float32)
    reads = []
    for _ in range(5):
        t = time.perf_counter()
        a.sum()
        reads.append(time.perf_counter() - t)
    b = np.random.default_rng(0).random((512, 512))
    products = []
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(5):
            t = time.perf_counter()
            b @ b
            products.append(time.perf_counter() - t)
    return {"load": os.getloadavg()[0], "cores": os.cpu_count(), "read_gb_s": a.nbytes / min(reads) / 1e9,
            "matmul_ms": 1000 * min(products)}


def probe_line() -> str:
    """The probe as one line."""
    p = probe()
    return (f"machine: load average {p['load']:.2f} on {p['cores']} cores; memory read {p['read_gb_s']:.1f} GB/s; "
            f"512x512 float64 product on one thread {p['matmul_ms']:.1f} ms")


if __name__ == "__main__":
    print(probe_line())
