"""Running a ``nogil`` compiled kernel over disjoint ranges on a few threads.

Used where one pass touches every map point (association, query scoring): two cores do it in
about half the time. Each range is computed exactly as a single call would
compute it, so results do not depend on the number of threads. The thread count follows
``NUMBA_NUM_THREADS`` (default: the CPUs this process may run on).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, TypeVar

import numba
import numpy as np

__all__ = ["map_ranges", "run_ranges", "map_bounds", "balanced_bounds", "one_blas_thread"]

T = TypeVar("T")

_blas = None
"""numpy's BLAS libraries (a threadpoolctl controller, made on first use)."""

_pool: ThreadPoolExecutor | None = None
_pool_pid = -1
_pool_lock = threading.Lock()


def _executor() -> ThreadPoolExecutor:
    """The helper threads (created on first use, and again in a forked child)."""
    global _pool, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_pid != os.getpid():
            workers = max(1, int(numba.config.NUMBA_NUM_THREADS) - 1)
            _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="cf-map")
            _pool_pid = os.getpid()
        return _pool


def _bounds(n: int, min_chunk: int) -> list[int]:
    parts = max(1, min(int(numba.config.NUMBA_NUM_THREADS), n // max(min_chunk, 1)))
    return [n * i // parts for i in range(parts + 1)]


def balanced_bounds(n: int, cost_cum, stride: int, *, min_chunk: int) -> list[int]:
    """Bounds ``[0, ..., n]`` of at most ``NUMBA_NUM_THREADS`` consecutive ranges of about equal
    cost, each of at least ``min_chunk`` items where the split allows it.

    ``cost_cum[i]`` is the (estimated) cost of items ``[0, i * stride)``, non-decreasing, with
    ``cost_cum[-1]`` the cost of all ``n``; a split lands on a multiple of ``stride``. Where the
    cost is even this is :func:`map_ranges`'s split; where it is not (work concentrated in some
    items), each thread gets its share of the work rather than of the items.
    """
    parts = max(1, min(int(numba.config.NUMBA_NUM_THREADS), n // max(min_chunk, 1)))
    cost = np.asarray(cost_cum, np.float64)
    total = float(cost[-1]) if len(cost) else 0.0
    if parts == 1 or not total > 0:
        return _bounds(n, min_chunk)
    bounds = [0]
    for k in range(1, parts):
        at = min(n, int(np.searchsorted(cost, total * k / parts)) * int(stride))
        if at > bounds[-1] and at < n:
            bounds.append(at)
    return bounds + [n]


def map_bounds(fn: Callable[[int, int], T], bounds: list[int]) -> list[T]:
    """``[fn(bounds[0], bounds[1]), fn(bounds[1], bounds[2]), ...]``, the ranges on the helper
    threads and the first on the calling thread, in range order."""
    if len(bounds) == 2:
        return [fn(bounds[0], bounds[1])]
    pool = _executor()
    futures = [pool.submit(fn, bounds[i], bounds[i + 1]) for i in range(1, len(bounds) - 1)]
    first = fn(bounds[0], bounds[1])
    return [first] + [f.result() for f in futures]


def map_ranges(fn: Callable[[int, int], T], n: int, *, min_chunk: int) -> list[T]:
    """``[fn(start, stop), ...]`` over ``[0, n)`` split into at most ``NUMBA_NUM_THREADS``
    ranges of at least ``min_chunk`` items, in range order; the calling thread runs the first."""
    return map_bounds(fn, _bounds(n, min_chunk))


def run_ranges(fn: Callable[[int, int], None], n: int, *, min_chunk: int) -> None:
    """Call ``fn(start, stop)`` over ``[0, n)`` as :func:`map_ranges` splits it."""
    map_ranges(fn, n, min_chunk=min_chunk)


def one_blas_thread():
    """A context in which numpy's BLAS runs on one thread (restored on exit).

    The map's matrix products are small (a frame's entries against the bank entries its points
    hold; the bank against one query), and OpenBLAS's helper threads spin for a while after each
    one, holding the core the compiled kernels split their ranges onto next: measured on a
    60-frame orbit with dense features, grouping a frame's rows took 12.8 ms after fusion's
    product and 8.2 ms with the product on one thread. Results are the same (the products split
    rows, not sums, across threads). The context costs about 40 us.
    """
    global _blas
    if _blas is None:
        from threadpoolctl import ThreadpoolController

        _blas = ThreadpoolController().select(user_api="blas")
    return _blas.limit(limits=1)
