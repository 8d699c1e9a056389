"""Dense per-pixel features in the palette form the map stores, exactly.

Encoders that label regions (a mask proposer plus CLIP, as in the paper) give many pixels the
same feature; gradslam and the reference ConceptFusion code hand such features over dense,
as an ``(H, W, d)`` array. :func:`palette_from_dense` finds the distinct rows in one pass over
the array: a pixel whose row is bit-for-bit the row of the pixel before it (the common case
inside a region) takes its id after one ``d``-word comparison; any other row is hashed over
all its words and looked up in an open-addressing table of the distinct rows found so far,
every candidate confirmed word by word, so the grouping is exact whatever the hash does.
The cost is one read of the array (about 160 MB at 240x320 with 512-d float32 features)
plus ``d`` multiply-adds for each row that starts a new run. Large frames are split into
blocks of rows grouped on several threads (``NUMBA_NUM_THREADS``); each later block's
distinct rows are then looked up among the earlier ones, so the palette and its order are
the same as from one pass.

Rows that are all zero (``0.0`` or ``-0.0``) mean "no feature". Non-finite values are
reported, never grouped silently.

For features with no repeats (LSeg-style dense encoders) every row is distinct, and an
exact palette is as large as the frame; see :mod:`conceptfusion.map.quantize` for the
bounded-memory path.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from conceptfusion._checks import as_float_array
from conceptfusion.map._rowhash import EMPTY, build_table, hash_weights, probe, row_hash, rows_equal
from conceptfusion.map._threads import map_ranges
from conceptfusion.perception.features import PixelFeatures

__all__ = ["palette_from_dense"]

_THREAD_ROWS = 1 << 14  # fewest pixels per thread


def palette_from_dense(feats_hwd) -> PixelFeatures:
    """The exact palette form of dense per-pixel features.

    Identical rows (bit for bit) share one palette entry; palette rows come in the order of
    their first pixel in raster order, so the result does not depend on hashing. All-zero
    rows get index -1 (no feature). Raises ``ValueError`` for NaN or infinite values.

    Shape:
        ``feats_hwd`` (H, W, d) float -> palette (P, d) float32, index (H, W) int32.
    """
    f = as_float_array("feats_hwd", feats_hwd, shape=(None, None, None))
    h, w, d = f.shape
    flat = np.ascontiguousarray(f.reshape(h * w, d), dtype=np.float32)
    if d == 0 or h * w == 0:
        return PixelFeatures(np.zeros((0, d), np.float32), np.full((h, w), -1, np.int32))
    bits = flat.view(np.int32)
    weights = hash_weights(d)
    parts = map_ranges(
        lambda start, stop: (start, *_group_rows(bits[start:stop], weights)), h * w, min_chunk=_THREAD_ROWS
    )
    _, first, index, finite = parts[0]
    if len(parts) > 1:
        index = np.concatenate([p[2] for p in parts])
        for start, part_first, part_index, part_finite in parts[1:]:
            first, remap = _merge_entries(bits, weights, first, part_first + start)
            stop = start + len(part_index)
            index[start:stop] = np.append(remap, np.int32(-1))[part_index]  # -1 stays -1
            finite = finite and part_finite
    if not finite:
        raise ValueError("feats_hwd: expected finite features, found NaN or inf")
    return PixelFeatures(flat[first], index.reshape(h, w))


@njit(cache=True, nogil=True)
def _row_kind(bits, r):
    """0: a feature; 1: all zero (no feature); 2: holds NaN or inf."""
    zero = True
    for k in range(bits.shape[1]):
        word = bits[r, k] & 0x7FFFFFFF
        if word >= 0x7F800000:
            return 2
        if word != 0:
            zero = False
    return 1 if zero else 0


@njit(cache=True, nogil=True)
def _group_rows(bits, weights):
    """Distinct rows of ``bits`` (N, d) int32 (float32 bit patterns).

    Returns ``(first, index, finite)``: for each distinct non-zero row, the index of its first
    occurrence, (P,) int64 in increasing order; each row's entry, (N,) int32, -1 for zero
    rows; and whether every row is finite.
    """
    n = bits.shape[0]
    index = np.empty(n, np.int32)
    cap = 1024
    table = np.full(cap, EMPTY, np.int64)  # distinct-row numbers by hash
    row_of = np.empty(64, np.int64)  # distinct-row number -> first row
    hash_of = np.empty(64, np.uint64)
    entry_of = np.empty(64, np.int32)  # distinct-row number -> palette entry (-1: zero row)
    num_rows = 0
    num_entries = 0
    finite = True
    for i in range(n):
        if i > 0 and rows_equal(bits, i, bits, i - 1):
            index[i] = index[i - 1]
            continue
        hv = row_hash(bits, i, weights)
        slot, found = probe(table, hash_of, row_of, bits, i, hv)
        if found < 0:
            if num_rows == len(row_of):
                row_of = _grow(row_of)
                hash_of = _grow(hash_of)
                entry_of = _grow(entry_of)
            kind = _row_kind(bits, i)
            if kind == 2:
                finite = False
            row_of[num_rows] = i
            hash_of[num_rows] = hv
            if kind == 0:
                entry_of[num_rows] = num_entries
                num_entries += 1
            else:
                entry_of[num_rows] = -1
            table[slot] = num_rows
            found = num_rows
            num_rows += 1
            if 2 * num_rows > cap:
                cap *= 4
                table = build_table(hash_of, num_rows, cap)
        index[i] = entry_of[found]
    first = np.empty(num_entries, np.int64)
    for r in range(num_rows):
        if entry_of[r] >= 0:
            first[entry_of[r]] = row_of[r]
    return first, index, finite


@njit(cache=True, nogil=True)
def _grow(a):
    out = np.empty(2 * len(a), a.dtype)
    out[: len(a)] = a
    return out


@njit(cache=True, nogil=True)
def _merge_entries(bits, weights, first_a, first_b):
    """Entries of a later block of rows (first rows ``first_b``) among the earlier blocks'
    (``first_a``), in order: returns the combined first rows, the earlier ones then the
    later block's new ones, and each later entry's combined number, (len(first_b),) int32."""
    na = first_a.shape[0]
    nb = first_b.shape[0]
    rows = np.empty(na + nb, np.int64)
    hashes = np.empty(na + nb, np.uint64)
    for r in range(na):
        rows[r] = first_a[r]
        hashes[r] = row_hash(bits, first_a[r], weights)
    cap = 1024
    while cap < 2 * (na + nb):
        cap *= 2
    table = build_table(hashes, na, cap)
    remap = np.empty(nb, np.int32)
    count = na
    for e in range(nb):
        r = first_b[e]
        hv = row_hash(bits, r, weights)
        slot, found = probe(table, hashes, rows, bits, r, hv)
        if found < 0:
            found = count
            rows[count] = r
            hashes[count] = hv
            table[slot] = count
            count += 1
        remap[e] = found
    return rows[:count], remap
