"""Compact storage of per-point concept vectors: a feature bank plus per-point mixtures.

The paper fuses a frame feature into a map point by a confidence-weighted running mean
(eq. 1). Started from nothing, that running mean is exactly the weighted mean of every
feature the point has seen, ``f_k = sum_t alpha_t f_t / sum_t alpha_t``. Frames hold few
distinct features (one per set of overlapping masks, see
:class:`conceptfusion.features.PixelFeatures`), so instead of a d-dimensional vector per
point the store keeps:

* a **bank** of distinct frame features, ``(B, d)`` float32, shared by all points;
* per point, a **history**: the ids of at most ``K`` bank entries the point has seen
  (histories are shared by every point with the same ids, so a point stores one int32);
* per point, ``K`` float32 **weights** (the summed confidences of each entry) and the
  float64 squared norm of the weighted sum ``S_k = sum_j w_kj b_j``, kept up to date so a
  cosine query needs no d-dimensional work per point.

The stored feature is exact (equal to eq. 1's running mean) while a point has seen at most
``K`` distinct features. A further distinct feature is credited to the point's most
similar stored entry (vector quantisation onto its own history); the map benchmark
reports what that costs in query scores against dense float32 fusion.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FeatureStore"]


class FeatureStore:
    """Bank, histories and per-point weights (see the module docstring).

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
        self._bank_sq = np.zeros(0, np.float64)  # squared norms of the bank rows
        self._num_bank = 0
        self._bank_keys: dict[bytes, int] = {}
        # History 0 is the empty history (a point that has seen no feature).
        self._hist_ids = np.full((1, slots), -1, np.int32)
        self._hist_len = np.zeros(1, np.int32)
        self._num_hist = 1
        self._hist_keys: dict[tuple[int, ...], int] = {(): 0}
        self.point_hist = np.zeros(0, np.int32)
        self.point_w = np.zeros((0, slots), np.float32)
        self.point_sq = np.zeros(0, np.float64)

    # ------------------------------------------------------------------ sizes
    @property
    def bank(self) -> np.ndarray:
        """Distinct features seen so far, (B, d) float32 (a view)."""
        return self._bank[: self._num_bank]

    @property
    def hist_ids(self) -> np.ndarray:
        """Bank ids of each history, (H, K) int32, -1 padded (a view)."""
        return self._hist_ids[: self._num_hist]

    @property
    def hist_len(self) -> np.ndarray:
        """Number of ids in each history, (H,) int32 (a view)."""
        return self._hist_len[: self._num_hist]

    def __len__(self) -> int:
        return int(self.point_hist.shape[0])

    def nbytes(self, num_points: int | None = None) -> int:
        """Bytes held for ``num_points`` points (all by default) plus the shared tables."""
        n = len(self) if num_points is None else num_points
        per_point = self.point_hist.itemsize + self.point_w.itemsize * self.slots + self.point_sq.itemsize
        return n * per_point + self.bank.nbytes + self.hist_ids.nbytes + self.hist_len.nbytes

    def resize(self, capacity: int) -> None:
        """Grow or shrink the per-point arrays to ``capacity`` rows (new rows: no feature)."""
        n = len(self)
        if capacity == n:
            return
        keep = min(n, capacity)
        hist = np.zeros(capacity, np.int32)
        w = np.zeros((capacity, self.slots), np.float32)
        sq = np.zeros(capacity, np.float64)
        hist[:keep], w[:keep], sq[:keep] = self.point_hist[:keep], self.point_w[:keep], self.point_sq[:keep]
        self.point_hist, self.point_w, self.point_sq = hist, w, sq

    # ------------------------------------------------------------------ bank and histories
    def add_to_bank(self, vectors_pd: np.ndarray) -> np.ndarray:
        """Bank ids of ``vectors_pd``'s rows, adding the ones not already stored (exact match).

        Shape:
            (P, d) -> (P,) int32.
        """
        vecs = np.ascontiguousarray(vectors_pd, dtype=np.float32)
        ids = np.empty(len(vecs), np.int32)
        new_rows = []
        for i, row in enumerate(vecs):
            key = row.tobytes()
            found = self._bank_keys.get(key)
            if found is None:
                found = self._num_bank + len(new_rows)
                self._bank_keys[key] = found
                new_rows.append(row)
            ids[i] = found
        if new_rows:
            self._bank = _grown(self._bank, self._num_bank + len(new_rows), fill=0.0)
            new = np.stack(new_rows)
            self._bank[self._num_bank : self._num_bank + len(new_rows)] = new
            self._bank_sq = _grown(self._bank_sq, self._num_bank + len(new_rows), fill=0.0)
            self._bank_sq[self._num_bank : self._num_bank + len(new_rows)] = np.einsum(
                "pd,pd->p", new.astype(np.float64), new.astype(np.float64)
            )
            self._num_bank += len(new_rows)
        return ids

    def _histories(self, keys: list[tuple[int, ...]]) -> np.ndarray:
        """History id of each id tuple, creating the missing ones; (len(keys),) int32."""
        out = np.empty(len(keys), np.int32)
        new = []
        for i, ids in enumerate(keys):
            found = self._hist_keys.get(ids)
            if found is None:
                found = self._num_hist + len(new)
                self._hist_keys[ids] = found
                new.append(ids)
            out[i] = found
        if new:
            end = self._num_hist + len(new)
            self._hist_ids = _grown(self._hist_ids, end, fill=-1)
            self._hist_len = _grown(self._hist_len, end, fill=0)
            for r, ids in enumerate(new, start=self._num_hist):
                self._hist_ids[r, : len(ids)] = ids
                self._hist_len[r] = len(ids)
            self._num_hist = end
        return out

    # ------------------------------------------------------------------ fusion
    def init_points(self, rows: np.ndarray, bank_ids: np.ndarray, alpha: np.ndarray) -> None:
        """Give freshly added points their first feature (``bank_ids < 0``: none).

        Shape:
            ``rows``, ``bank_ids``, ``alpha``: (M,).
        """
        self.point_hist[rows] = 0
        self.point_w[rows] = 0.0
        self.point_sq[rows] = 0.0
        has = bank_ids >= 0
        if not has.any():
            return
        rows, ids, a = rows[has], bank_ids[has], alpha[has].astype(np.float32)
        uniq, inv = np.unique(ids, return_inverse=True)
        hist_of = self._histories([(int(b),) for b in uniq])
        self.point_hist[rows] = hist_of[inv]
        self.point_w[rows, 0] = a
        self.point_sq[rows] = a.astype(np.float64) ** 2 * self._bank_sq[uniq][inv]

    def merge(self, rows: np.ndarray, bank_ids: np.ndarray, alpha: np.ndarray) -> None:
        """Fuse one observation into each existing point (paper eq. 1 on the stored mixture).

        Rows must be distinct. Entries with ``bank_ids < 0`` (no feature) are ignored, so
        zero features never dilute a point's feature.

        Shape:
            ``rows``, ``bank_ids``, ``alpha``: (M,).
        """
        has = bank_ids >= 0
        rows, ids, a = rows[has], bank_ids[has], alpha[has].astype(np.float64)
        if rows.size == 0:
            return
        hist = self.point_hist[rows]
        # Points sharing (history, new id) take the same transition: work per group.
        group_key = hist.astype(np.int64) * (len(self.bank) + 1) + ids
        keys, first, inv = np.unique(group_key, return_index=True, return_inverse=True)
        g_hist, g_new = hist[first], ids[first]
        g_atoms = self.hist_ids[g_hist]  # (G, K), -1 padded
        g_len = self.hist_len[g_hist]
        valid_slot = np.arange(self.slots)[None, :] < g_len[:, None]
        dots_new = self._pair_dots(g_atoms, g_new)  # <b_j, b_new>, (G, K)
        hit = (g_atoms == g_new[:, None]) & valid_slot
        g_slot = np.empty(len(keys), np.int64)
        g_next = g_hist.copy()
        g_credit = g_new.copy()  # the bank entry the observation is credited to
        has_hit = hit.any(axis=1)
        g_slot[has_hit] = hit[has_hit].argmax(axis=1)
        room = ~has_hit & (g_len < self.slots)
        g_slot[room] = g_len[room]
        if room.any():
            grow = np.flatnonzero(room)
            g_next[grow] = self._histories(
                [tuple(g_atoms[gi, : g_len[gi]].tolist()) + (int(g_new[gi]),) for gi in grow]
            )
        full = ~has_hit & ~room
        g_dots = dots_new
        if full.any():
            # Credit the observation to the most similar stored entry.
            j = np.where(valid_slot[full], dots_new[full], -np.inf).argmax(axis=1)
            g_slot[full] = j
            g_credit[full] = g_atoms[full, j]
            g_dots = dots_new.copy()
            g_dots[full] = self._pair_dots(g_atoms[full], g_credit[full])
        g_sq_e = self._bank_sq[g_credit]  # |credited vector|^2
        # Per point: |S + a e|^2 = |S|^2 + 2 a <S, e> + a^2 |e|^2 with <S, e> = sum_j w_j <b_j, e>.
        s_dot_e = np.einsum("mk,mk->m", self.point_w[rows], g_dots[inv].astype(np.float32)).astype(np.float64)
        self.point_sq[rows] = np.maximum(self.point_sq[rows] + 2.0 * a * s_dot_e + a * a * g_sq_e[inv], 0.0)
        self.point_w[rows, g_slot[inv]] += a.astype(np.float32)
        self.point_hist[rows] = g_next[inv]

    def _pair_dots(self, atoms_gk: np.ndarray, other_g: np.ndarray) -> np.ndarray:
        """``<bank[atoms_gk[g, j]], bank[other_g[g]]>`` (0 where the atom id is -1), (G, K) float64.

        Computed as one small matrix product over the distinct ids involved.
        """
        ua, ia = np.unique(np.maximum(atoms_gk, 0), return_inverse=True)
        uo, io = np.unique(other_g, return_inverse=True)
        block = self.bank[ua].astype(np.float64) @ self.bank[uo].astype(np.float64).T
        dots = block[ia.reshape(atoms_gk.shape), io.reshape(-1)[:, None]]
        dots[atoms_gk < 0] = 0.0
        return dots

    # ------------------------------------------------------------------ reading
    def feature_weight(self, n: int) -> np.ndarray:
        """Total feature confidence of the first ``n`` points, (n,)."""
        return self.point_w[:n].sum(axis=1)

    def scores(self, query_d: np.ndarray, n: int) -> np.ndarray:
        """Cosine similarity of each of the first ``n`` points' feature with a query.

        Points without a feature get NaN.

        Shape:
            (d,) -> (n,) float32.
        """
        q = np.asarray(query_d, np.float32)
        q = q / max(float(np.linalg.norm(q)), 1e-12)
        bank_scores = np.append(self.bank @ q, np.float32(0.0))  # id -1 -> 0
        hist_scores = bank_scores[self.hist_ids]  # (H, K); -1 indexes the appended 0
        num = np.einsum("nk,nk->n", self.point_w[:n], hist_scores[self.point_hist[:n]])
        norm = np.sqrt(self.point_sq[:n]).astype(np.float32)
        with np.errstate(invalid="ignore", divide="ignore"):
            out = num / norm
        out[self.point_hist[:n] == 0] = np.nan
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
            atoms = self.hist_ids[self.point_hist[sel]]  # (m, K), -1 -> zero row
            f = np.einsum("mk,mkd->md", self.point_w[sel], bank[atoms])
            norm = np.linalg.norm(f, axis=1, keepdims=True)
            out[s : s + chunk] = np.where(norm > 0, f / np.maximum(norm, 1e-12), 0.0)
        return out

    # ------------------------------------------------------------------ persistence
    def state(self, n: int) -> dict[str, np.ndarray]:
        """Arrays that reproduce the store exactly (first ``n`` points)."""
        return {
            "feat_bank": self.bank,
            "feat_hist_ids": self.hist_ids,
            "feat_hist_len": self.hist_len,
            "feat_point_hist": self.point_hist[:n],
            "feat_point_w": self.point_w[:n],
            "feat_point_sq": self.point_sq[:n],
        }

    @classmethod
    def from_state(cls, dim: int, slots: int, arrays: dict[str, np.ndarray]) -> "FeatureStore":
        """Rebuild a store from :meth:`state` arrays (validated by the caller's loader)."""
        store = cls(dim, slots)
        store._bank = np.array(arrays["feat_bank"], np.float32)
        store._num_bank = len(store._bank)
        store._bank_sq = np.einsum("pd,pd->p", store._bank.astype(np.float64), store._bank.astype(np.float64))
        store._bank_keys = {row.tobytes(): i for i, row in enumerate(store.bank)}
        store._hist_ids = np.array(arrays["feat_hist_ids"], np.int32)
        store._hist_len = np.array(arrays["feat_hist_len"], np.int32)
        store._num_hist = len(store._hist_len)
        store._hist_keys = {
            tuple(int(x) for x in ids[:length]): i for i, (ids, length) in enumerate(zip(store.hist_ids, store.hist_len))
        }
        store.point_hist = np.array(arrays["feat_point_hist"], np.int32)
        store.point_w = np.array(arrays["feat_point_w"], np.float32)
        store.point_sq = np.array(arrays["feat_point_sq"], np.float64)
        return store


def _grown(arr: np.ndarray, rows: int, *, fill) -> np.ndarray:
    """``arr`` with at least ``rows`` rows, growing capacity geometrically (amortised O(1))."""
    if rows <= len(arr):
        return arr
    out = np.full((max(rows, 2 * len(arr) + 64),) + arr.shape[1:], fill, dtype=arr.dtype)
    out[: len(arr)] = arr
    return out
