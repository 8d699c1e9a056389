"""Exact lookup of float32 rows by their bit patterns (compiled, numba).

Rows are hashed over all their 32-bit words (a sum of word times fixed odd 64-bit
multipliers, vectorised) and kept in open-addressing tables of row numbers; a hash match is
always confirmed word by word, so lookups are exact whatever the hash does. Used to group
the rows of a dense feature array (:mod:`conceptfusion.map.dense`) and to find a frame's
features in the map's bank (:class:`conceptfusion.map.feature_store.FeatureStore`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["hash_weights", "row_hashes", "rows_equal", "row_hash", "build_table", "lookup_or_add", "EMPTY"]

EMPTY = -1
"""Table slot holding no row."""


def hash_weights(d: int) -> np.ndarray:
    """Fixed odd 64-bit multipliers, one per word of a ``d``-word row, (d,) uint64."""
    return np.random.default_rng(0x5EED).integers(0, 2**63, d, dtype=np.uint64) * np.uint64(2) + np.uint64(1)


@njit(cache=True, nogil=True)
def rows_equal(bits_a, a, bits_b, b):
    """Row ``a`` of ``bits_a`` and row ``b`` of ``bits_b`` hold the same words (branch-free pass)."""
    if bits_a[a, 0] != bits_b[b, 0]:
        return False
    diff = np.int32(0)
    for k in range(bits_a.shape[1]):
        diff |= bits_a[a, k] ^ bits_b[b, k]
    return diff == 0


@njit(cache=True, nogil=True)
def row_hash(bits, r, weights):
    """Hash of row ``r`` of ``bits`` (N, d) int32, uint64."""
    acc = np.uint64(0)
    for k in range(bits.shape[1]):
        acc += np.uint64(np.uint32(bits[r, k])) * weights[k]
    return acc ^ (acc >> np.uint64(29))


@njit(cache=True, nogil=True)
def probe(table, hash_of, row_of, bits, r, hv):
    """Find row ``r`` of ``bits`` (hash ``hv``) in an open-addressing ``table`` (power-of-two
    size) whose entries index ``hash_of`` / ``row_of``: ``(slot, entry)`` with ``entry`` -1 and
    ``slot`` the free slot where it would go when absent."""
    mask = table.shape[0] - 1
    slot = np.int64(hv & np.uint64(mask))
    while table[slot] != EMPTY:
        e = table[slot]
        if hash_of[e] == hv and rows_equal(bits, r, bits, row_of[e]):
            return slot, e
        slot = (slot + 1) & mask
    return slot, -1


@njit(cache=True, nogil=True)
def row_hashes(bits, weights):
    """Hash of every row of ``bits`` (N, d) int32, (N,) uint64."""
    out = np.empty(bits.shape[0], np.uint64)
    for r in range(bits.shape[0]):
        out[r] = row_hash(bits, r, weights)
    return out


@njit(cache=True, nogil=True)
def build_table(hashes, count, capacity):
    """An open-addressing table (capacity a power of two) of rows ``0..count-1`` by hash."""
    table = np.full(capacity, EMPTY, np.int64)
    mask = capacity - 1
    for r in range(count):
        s = np.int64(hashes[r] & np.uint64(mask))
        while table[s] != EMPTY:
            s = (s + 1) & mask
        table[s] = r
    return table


@njit(cache=True, nogil=True)
def lookup_or_add(table, known_bits, known_hashes, num_known, bits, hashes):
    """Ids of the rows of ``bits`` among ``num_known`` known rows, adding the new ones.

    ``table`` indexes the known rows by hash (:func:`build_table`) and must have room for
    all of them plus every row of ``bits`` at most half full; it is updated in place. A
    row found nowhere gets the next id (``num_known``, ``num_known + 1``, ...), in row order;
    repeats within ``bits`` share one. Returns ``(ids, new_rows)``: (P,) int32 and the rows
    of ``bits`` that were added, (A,) int64 in id order.
    """
    p = bits.shape[0]
    mask = table.shape[0] - 1
    ids = np.empty(p, np.int32)
    new_rows = np.empty(p, np.int64)
    added = 0
    for i in range(p):
        hv = hashes[i]
        s = np.int64(hv & np.uint64(mask))
        found = -1
        while table[s] != EMPTY:
            r = table[s]
            if r < num_known:
                if known_hashes[r] == hv and rows_equal(bits, i, known_bits, r):
                    found = r
                    break
            else:
                j = new_rows[r - num_known]
                if hashes[j] == hv and rows_equal(bits, i, bits, j):
                    found = r
                    break
            s = (s + 1) & mask
        if found < 0:
            found = num_known + added
            new_rows[added] = i
            added += 1
            table[s] = found
        ids[i] = found
    return ids, new_rows[:added]
