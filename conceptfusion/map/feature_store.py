"""Compact storage of per-point concept vectors: a feature bank plus per-point mixtures.

The paper fuses a frame feature into a map point by a confidence-weighted running mean
(eq. 1). Started from nothing, that running mean is exactly the weighted mean of every
feature the point has seen, ``f_k = sum_t alpha_t f_t / sum_t alpha_t``. Frames hold few
distinct features (one per set of overlapping masks, see
:class:`conceptfusion.perception.features.PixelFeatures`), so instead of a d-dimensional vector per
point the store keeps:

* a **bank** of distinct frame features, ``(B, d)`` float32, shared by all points; a frame's
  features are looked up by a hash of their bits (an open-addressing table of bank rows,
  every match confirmed word by word), so a feature seen again is stored once;
* the squared norm of each bank entry, ``(B,)`` float32;
* per point, the ids of at most ``K`` bank entries it has seen, their summed confidences
  ``w`` (float32), the off-diagonal Gram entries of those bank entries (strict upper
  triangle, float32; the diagonal is the bank's squared norms) and the squared norm of the
  weighted sum ``S_k = sum_j w_kj b_j`` (float64): ``8K + 2K(K - 1) + 8`` bytes, 184 for
  ``K = 8``.

The Gram matrix lets every update keep ``|S_k|^2`` exact without touching d-dimensional
data, so a cosine query costs ``K`` multiply-adds per point. The stored feature is exact
(equal to eq. 1's running mean) while a point has seen at most ``K`` distinct features; a
further one is credited to the point's most similar stored entry (vector quantisation
onto its own history). ``benchmarks/bench_mapping.py`` reports what that costs in query
scores against exact running means. Bank entries no point refers to any more are dropped
by :meth:`FeatureStore.compact`.
"""

from __future__ import annotations

import numpy as np

from conceptfusion.map import _kernels
from conceptfusion.map._rowhash import EMPTY, build_table, hash_weights, lookup_or_add, row_hashes
from conceptfusion.map._threads import one_blas_thread, run_ranges

__all__ = ["FeatureStore"]

_MIN_TABLE = 1024
_SCORE_CHUNK = 1 << 18
"""Fewest points per thread when scoring: below this one thread is faster than two."""


class FeatureStore:
    """Bank and per-point mixtures (see the module docstring).

    Args:
        dim: feature dimension ``d``.
        slots: ``K``, the number of distinct bank entries a point keeps exactly.
    """

    def __init__(self, dim: int, slots: int = 8) -> None:
        if dim <= 0 or slots <= 0:
            raise ValueError(f"dim, slots: expected positive integers, got {dim}, {slots}")
        self.dim = int(dim)
        self.slots = int(slots)
        self._bank = np.zeros((0, dim), np.float32)
        self._bank_sq = np.zeros(0, np.float32)
        self._bank_hash = np.zeros(0, np.uint64)
        self._num_bank = 0
        self._hash_weights = hash_weights(self.dim)
        self._table = np.full(_MIN_TABLE, EMPTY, np.int64)  # bank rows by hash of their bits
        self._bank_at_compact = 0
        self.point_ids = np.full((0, slots), -1, np.int32)
        self.point_w = np.zeros((0, slots), np.float32)
        self.point_gram = np.zeros((0, slots * (slots - 1) // 2), np.float32)
        self.point_sq = np.zeros(0, np.float64)

    # ------------------------------------------------------------------ sizes
    @property
    def bank(self) -> np.ndarray:
        """Distinct features in use, (B, d) float32 (a view)."""
        return self._bank[: self._num_bank]

    def bytes_per_point(self) -> int:
        """Bytes each point holds in this store."""
        return (
            self.point_ids.itemsize * self.slots
            + self.point_w.itemsize * self.slots
            + self.point_gram.itemsize * self.point_gram.shape[1]
            + self.point_sq.itemsize
        )

    def nbytes(self, num_points: int) -> int:
        """Bytes held for ``num_points`` points plus the shared bank (rows, squared norms,
        hashes and the hash table)."""
        per_entry = self._bank.itemsize * self.dim + self._bank_sq.itemsize + self._bank_hash.itemsize
        return num_points * self.bytes_per_point() + self._num_bank * per_entry + self._table.nbytes

    def resize(self, capacity: int, num_points: int) -> None:
        """Reallocate the per-point arrays to ``capacity`` rows, keeping ``num_points``.

        Rows past ``num_points`` are left uninitialised until :meth:`clear_rows`.
        """
        keep = min(num_points, capacity)

        def grow(arr):
            out = np.empty((capacity,) + arr.shape[1:], arr.dtype)
            out[:keep] = arr[:keep]
            return out

        self.point_ids = grow(self.point_ids)
        self.point_w = grow(self.point_w)
        self.point_gram = grow(self.point_gram)
        self.point_sq = grow(self.point_sq)

    def clear_rows(self, start: int, stop: int) -> None:
        """Reset rows ``start:stop`` to "no feature" (before new points use them)."""
        self.point_ids[start:stop] = -1
        self.point_w[start:stop] = 0.0
        self.point_gram[start:stop] = 0.0
        self.point_sq[start:stop] = 0.0

    # ------------------------------------------------------------------ bank
    def add_to_bank(self, vectors_pd: np.ndarray) -> np.ndarray:
        """Bank ids of ``vectors_pd``'s rows, adding the ones not already stored (exact match).

        Rows match when their float32 bit patterns are equal; new rows get the next ids in
        row order (repeats share one).

        Shape:
            (P, d) -> (P,) int32.
        """
        vecs = np.ascontiguousarray(vectors_pd, dtype=np.float32)
        if len(vecs) == 0:
            return np.zeros(0, np.int32)
        bits = vecs.view(np.int32)
        hashes = row_hashes(bits, self._hash_weights)
        self._reserve_table(self._num_bank + len(vecs))
        ids, new_rows = lookup_or_add(
            self._table, self.bank.view(np.int32), self._bank_hash, self._num_bank, bits, hashes
        )
        if len(new_rows):
            end = self._num_bank + len(new_rows)
            if end > len(self._bank):
                cap = max(end, 2 * len(self._bank) + 256)
                self._bank = _grown(self._bank, cap, self._num_bank)
                self._bank_sq = _grown(self._bank_sq, cap, self._num_bank)
                self._bank_hash = _grown(self._bank_hash, cap, self._num_bank)
            rows = vecs[new_rows]
            self._bank[self._num_bank : end] = rows
            self._bank_sq[self._num_bank : end] = _squared_norms(rows)
            self._bank_hash[self._num_bank : end] = hashes[new_rows]
            self._num_bank = end
        return ids

    def _reserve_table(self, entries: int) -> None:
        """Rebuild the hash table if ``entries`` rows would fill it past half."""
        if 2 * entries > len(self._table):
            self._table = build_table(self._bank_hash, self._num_bank, _table_capacity(entries))

    def compact(self, num_points: int) -> int:
        """Drop bank entries that no point refers to; returns how many were dropped."""
        ids = self.point_ids[:num_points]
        used = np.zeros(self._num_bank, bool)
        used[ids[ids >= 0]] = True
        dropped = int(self._num_bank - used.sum())
        if dropped:
            remap = np.full(self._num_bank + 1, -1, np.int32)
            remap[:-1][used] = np.arange(int(used.sum()), dtype=np.int32)
            ids[...] = remap[ids]  # -1 maps to remap[-1] = -1
            kept = self.bank[used]
            self._bank = kept.copy()
            self._bank_sq = self._bank_sq[: self._num_bank][used].copy()
            self._bank_hash = self._bank_hash[: self._num_bank][used].copy()
            self._num_bank = len(kept)
            self._table = build_table(self._bank_hash, self._num_bank, len(self._table))
        self._bank_at_compact = self._num_bank
        return dropped

    def maybe_compact(self, num_points: int) -> None:
        """Compact when the bank has doubled (plus some slack) since the last compaction."""
        if self._num_bank > 2 * self._bank_at_compact + 4096:
            self.compact(num_points)

    # ------------------------------------------------------------------ fusion
    def _frame_block(self, rows: np.ndarray, new_ids: np.ndarray):
        """Dot products between the bank entries held by ``rows`` and the frame's entries.

        Returns ``(lut_atom, lut_new, block)``: bank id -> row / column of ``block`` (-1
        where unused) and ``block`` (A, P) float32.
        """
        atoms, lut_atom, cols, lut_new = _kernels.lookup_tables(self.point_ids, rows, new_ids, self._num_bank)
        if len(atoms) == 0:  # fresh points: no dot products needed
            return lut_atom, lut_new, np.zeros((0, len(cols)), np.float32)
        with one_blas_thread():
            block = self.bank[atoms] @ self.bank[cols].T
        return lut_atom, lut_new, np.ascontiguousarray(block, np.float32)

    def add_observations(self, rows: np.ndarray, bank_ids: np.ndarray, alpha: np.ndarray) -> None:
        """Fuse one observation into each point (paper eq. 1 on the stored mixture).

        Works for fresh points (no ids yet) and existing ones. Rows must be distinct.
        Entries with ``bank_ids < 0`` (no feature) are ignored, so zero features never
        dilute a point's feature.

        Shape:
            ``rows``, ``bank_ids``, ``alpha``: (M,).
        """
        has = bank_ids >= 0
        rows = np.ascontiguousarray(rows[has], np.int64)
        ids = np.ascontiguousarray(bank_ids[has], np.int32)
        a = np.ascontiguousarray(alpha[has], np.float32)
        if rows.size == 0:
            return
        lut_atom, lut_new, block = self._frame_block(rows, ids)
        _kernels.merge_features(
            self.point_ids, self.point_w, self.point_gram, self.point_sq, self._bank_sq,
            rows, ids, a, lut_atom, lut_new, block,
        )

    # ------------------------------------------------------------------ reading
    def feature_weight(self, n: int) -> np.ndarray:
        """Total feature confidence of the first ``n`` points, (n,)."""
        return self.point_w[:n].sum(axis=1)

    def has_feature(self, n: int) -> np.ndarray:
        """Whether each of the first ``n`` points holds a feature, (n,) bool."""
        return self.point_ids[:n, 0] >= 0

    def scores(self, query_d: np.ndarray, n: int) -> np.ndarray:
        """Cosine similarity of each of the first ``n`` points' feature with a query.

        Points without a feature get NaN.

        Shape:
            (d,) -> (n,) float32.
        """
        q = np.asarray(query_d, np.float32)
        q = q / max(float(np.linalg.norm(q)), 1e-12)
        with one_blas_thread():
            bank_scores = np.ascontiguousarray(self.bank @ q, np.float32)
        out = np.empty(n, np.float32)
        ids, w, sq = self.point_ids, self.point_w, self.point_sq

        def score(start: int, stop: int) -> None:
            _kernels.mixture_scores(ids, w, sq, bank_scores, start, stop, out)

        run_ranges(score, n, min_chunk=_SCORE_CHUNK)
        return out

    def scores_many(self, queries_qd: np.ndarray, n: int) -> np.ndarray:
        """:meth:`scores` of several queries in one pass over the points, each row equal to
        what :meth:`scores` returns for that query.

        Shape:
            (Q, d) -> (Q, n) float32.
        """
        qs = np.asarray(queries_qd, np.float32).reshape(-1, self.dim)
        cols = []
        with one_blas_thread():
            for q in qs:  # one matrix-vector product per query, rounded as in scores()
                q = q / max(float(np.linalg.norm(q)), 1e-12)
                cols.append(np.ascontiguousarray(self.bank @ q, np.float32))
        bank_scores = np.ascontiguousarray(np.stack(cols)) if cols else np.zeros((0, self._num_bank), np.float32)
        out = np.empty((len(qs), n), np.float32)
        ids, w, sq = self.point_ids, self.point_w, self.point_sq

        def score(start: int, stop: int) -> None:
            _kernels.mixture_scores_many(ids, w, sq, bank_scores, start, stop, out)

        if len(qs):
            run_ranges(score, n, min_chunk=_SCORE_CHUNK)
        return out

    def features(self, idx: np.ndarray, *, chunk: int = 65536) -> np.ndarray:
        """Unit-length features of the given points (zeros for points without one).

        Shape:
            ``idx`` (M,) -> (M, d) float32.
        """
        out = np.zeros((len(idx), self.dim), np.float32)
        bank = np.concatenate([self.bank, np.zeros((1, self.dim), np.float32)])
        for s in range(0, len(idx), chunk):
            sel = idx[s : s + chunk]
            f = np.einsum("mk,mkd->md", self.point_w[sel], bank[self.point_ids[sel]])  # id -1 -> zero row
            norm = np.linalg.norm(f, axis=1, keepdims=True)
            out[s : s + chunk] = np.where(norm > 0, f / np.maximum(norm, 1e-12), 0.0)
        return out

    # ------------------------------------------------------------------ persistence
    def state(self, n: int) -> dict[str, np.ndarray]:
        """Arrays that reproduce the store exactly (first ``n`` points).

        ``feat_point_gram`` is the full upper triangle (diagonal included) of each point's
        Gram matrix, row-major, ``K(K + 1) / 2`` columns.
        """
        ids = self.point_ids[:n]
        diag_idx, off_idx = _tri_columns(self.slots)
        gram = np.zeros((n, len(diag_idx) + len(off_idx)), np.float32)
        gram[:, off_idx] = self.point_gram[:n]
        sq = np.append(self._bank_sq[: self._num_bank], np.float32(0.0))  # id -1: an empty slot
        gram[:, diag_idx] = sq[ids]
        return {
            "feat_bank": self.bank,
            "feat_point_ids": ids,
            "feat_point_w": self.point_w[:n],
            "feat_point_gram": gram,
            "feat_point_sq": self.point_sq[:n],
        }

    @classmethod
    def from_state(cls, dim: int, slots: int, arrays: dict[str, np.ndarray]) -> "FeatureStore":
        """Rebuild a store from :meth:`state` arrays (validated by the caller's loader)."""
        store = cls(dim, slots)
        store._bank = np.array(arrays["feat_bank"], np.float32).reshape(-1, dim)
        store._num_bank = store._bank_at_compact = len(store._bank)
        store._bank_sq = _squared_norms(store._bank)
        store._bank_hash = row_hashes(store._bank.view(np.int32), store._hash_weights)
        store._table = build_table(store._bank_hash, store._num_bank, _table_capacity(store._num_bank))
        store.point_ids = np.array(arrays["feat_point_ids"], np.int32)
        store.point_w = np.array(arrays["feat_point_w"], np.float32)
        _, off_idx = _tri_columns(slots)
        store.point_gram = np.ascontiguousarray(np.asarray(arrays["feat_point_gram"], np.float32)[:, off_idx])
        store.point_sq = np.array(arrays["feat_point_sq"], np.float64)
        return store


def _table_capacity(entries: int) -> int:
    """A power of two at least four times ``entries`` (so a table stays at most half full)."""
    return max(_MIN_TABLE, 1 << max(4 * entries - 1, 1).bit_length())


def _grown(a: np.ndarray, capacity: int, keep: int) -> np.ndarray:
    """``a`` reallocated to ``capacity`` rows (zeros past ``keep``)."""
    out = np.zeros((capacity,) + a.shape[1:], a.dtype)
    out[:keep] = a[:keep]
    return out


def _squared_norms(rows_pd: np.ndarray) -> np.ndarray:
    """Squared norms of the rows, (P,) float32 (each row's sum is the same whatever the array)."""
    return np.einsum("pd,pd->p", rows_pd, rows_pd).astype(np.float32)


def _tri_columns(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Columns of the row-major upper triangle (diagonal included) of a ``k x k`` matrix
    holding the diagonal, (k,), and the off-diagonal pairs in the store's packed order,
    (k(k - 1) / 2,): pair ``(i, j)``, ``i < j``, is packed at ``j (j - 1) / 2 + i``."""
    full = np.full((k, k), -1, np.int64)
    iu, ju = np.triu_indices(k)
    full[iu, ju] = np.arange(len(iu))
    diag = full[np.arange(k), np.arange(k)]
    off = np.array([full[i, j] for j in range(k) for i in range(j)], np.int64)
    return diag, off
