"""Pixel-aligned features from a global embedding and per-region embeddings (paper eqs. 3-6).

For an image with global embedding ``f_G`` and ``R`` class-agnostic masks with local (crop)
embeddings ``f_L_i``:

* ``phi_i = cos(f_L_i, f_G)`` (eq. 3);
* ``phibar_i = (1/R) * sum_{j != i} cos(f_L_i, f_L_j)``: how much region ``i`` resembles the
  other regions (eq. 4, the *uniqueness* term);
* ``w_i = softmax_i((phi_i + phibar_i) / tau)`` over the regions (eq. 5), without ``phibar``
  when ``uniqueness=False``;
* ``f_P_i = w_i f_G + (1 - w_i) f_L_i``, L2-normalised (eq. 6).

``mode`` selects the paper's ablation variants: ``"full"`` (eqs. 3-6, the default),
``"global"`` (``w_i = 1``: every masked pixel gets ``f_G``) and ``"local"`` (``w_i = 0``:
each region keeps its own ``f_L_i``).

``f_G`` and every ``f_L_i`` are L2-normalised before mixing (foundation-model embeddings
are compared by cosine, so their length carries no meaning). A pixel covered by several
masks gets the L2-normalised sum of their ``f_P_i``, independent of mask order; a pixel
covered by no mask gets the zero vector.

Because a pixel's feature depends only on the *set* of masks covering it, a frame holds
few distinct features. :class:`PixelFeatures` keeps them as a palette plus a per-pixel
index, which is what the map consumes; :meth:`PixelFeatures.dense` expands it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from conceptfusion._checks import as_array, as_float_array
from conceptfusion.errors import ShapeError

__all__ = [
    "PixelFeatures",
    "cosine",
    "mixing_weights",
    "region_features",
    "pixel_aligned_palette",
    "pixel_aligned_features",
    "mask_bboxes",
    "crop_masks",
    "FEATURE_MODES",
    "check_mode",
]

_EPS = 1e-8

FEATURE_MODES = ("full", "global", "local")
"""Pixel-feature variants: eqs. 3-6, global embedding only, local (crop) embeddings only."""


def check_mode(mode) -> str:
    """``mode`` if it is one of :data:`FEATURE_MODES`; ``ValueError`` naming them otherwise."""
    if mode not in FEATURE_MODES:
        raise ValueError(f"mode: expected one of {FEATURE_MODES}, got {mode!r}")
    return mode


@dataclass(frozen=True)
class PixelFeatures:
    """Pixel-aligned features of one frame in palette form.

    Shape:
        ``palette_pd`` (P, d) float32, rows unit length; ``index_hw`` (H, W) int32 row of
        ``palette_pd`` for each pixel, -1 where the pixel has no feature.
    """

    palette_pd: np.ndarray
    """Distinct features of the frame, one per row."""
    index_hw: np.ndarray
    """Per-pixel row of ``palette_pd``; -1 means "no feature" (the zero vector)."""

    def __post_init__(self) -> None:
        pal = as_float_array("palette_pd", self.palette_pd, shape=(None, None))
        idx = as_array("index_hw", self.index_hw, shape=(None, None), kinds="iu")
        if idx.size and (idx.min() < -1 or idx.max() >= pal.shape[0]):
            raise ShapeError(
                f"index_hw: expected values in [-1, {pal.shape[0] - 1}], "
                f"got range [{idx.min()}, {idx.max()}]"
            )

    @property
    def dim(self) -> int:
        return int(self.palette_pd.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.index_hw.shape)  # type: ignore[return-value]

    def dense(self) -> np.ndarray:
        """Expand to per-pixel features; pixels without a feature get zeros.

        Shape:
            returns (H, W, d) float32.
        """
        table = np.concatenate([self.palette_pd.astype(np.float32), np.zeros((1, self.dim), np.float32)])
        return table[np.where(self.index_hw < 0, len(self.palette_pd), self.index_hw)]

    @classmethod
    def from_dense(cls, feats_hwd: np.ndarray) -> "PixelFeatures":
        """Palette form of dense per-pixel features (exact: identical rows share an entry).

        All-zero rows mean "no feature". Rows need not be unit length; they are stored as
        given (the map normalises where it compares).

        Shape:
            ``feats_hwd`` (H, W, d) float -> palette (P, d), index (H, W).
        """
        f = as_float_array("feats_hwd", feats_hwd, shape=(None, None, None))
        h, w, d = f.shape
        flat = np.ascontiguousarray(f.reshape(h * w, d), dtype=np.float32)
        nonzero = np.any(flat != 0, axis=1)
        index = np.full(h * w, -1, dtype=np.int32)
        if not nonzero.any():
            return cls(np.zeros((0, d), np.float32), index.reshape(h, w))
        rows = flat[nonzero]
        # Group rows by a random projection (cheap), then confirm that every row equals its
        # group's representative; only a hash collision falls back to exact row grouping.
        proj = rows @ np.random.default_rng(0).standard_normal((d, 2)).astype(np.float32)
        _, first, inverse = _unique_rows(np.ascontiguousarray(proj))
        if not np.array_equal(rows[first][inverse], rows):
            _, first, inverse = _unique_rows(rows)
        index[nonzero] = inverse.astype(np.int32)
        return cls(rows[first], index.reshape(h, w))


def _unique_rows(rows_nk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.unique`` over whole rows (by their bytes): unique keys, first index, inverse."""
    keys = rows_nk.view(np.dtype((np.void, rows_nk.dtype.itemsize * rows_nk.shape[1]))).ravel()
    uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    return uniq, first, inverse.ravel()


@njit(cache=True, nogil=True)
def _mask_set_codes(masks_rn):
    """The set of masks covering each pixel as bits, mask ``i`` at bit ``63 - i`` (so codes
    order as the rows of ``np.packbits(masks, axis=0).T`` compare bytewise).

    Shape:
        (R, N) bool, R <= 64 -> (N,) uint64.
    """
    r, n = masks_rn.shape
    out = np.zeros(n, np.uint64)
    for i in range(r):
        bit = np.uint64(1) << np.uint64(63 - i)
        for j in range(n):
            if masks_rn[i, j]:
                out[j] |= bit
    return out


def cosine(a_nd: np.ndarray, b_md: np.ndarray) -> np.ndarray:
    """Cosine similarity matrix ``a.b / (|a| |b| + eps)`` (paper eq. 3).

    Shape:
        (N, d), (M, d) -> (N, M) float64.
    """
    a = np.asarray(a_nd, dtype=np.float64)
    b = np.asarray(b_md, dtype=np.float64)
    na = np.linalg.norm(a, axis=1)[:, None]
    nb = np.linalg.norm(b, axis=1)[None, :]
    return (a @ b.T) / (na * nb + _EPS)


def _unit(x: np.ndarray) -> np.ndarray:
    return x / (np.linalg.norm(x, axis=-1, keepdims=True) + _EPS)


def _check_embeddings(global_feat_d, local_feats_rd) -> tuple[np.ndarray, np.ndarray]:
    g = as_float_array("global_feat_d", global_feat_d, shape=(None,))
    local = as_float_array("local_feats_rd", local_feats_rd, shape=(None, g.shape[0]))
    for name, arr in (("global_feat_d", g), ("local_feats_rd", local)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name}: expected finite values, found NaN or inf")
    return g.astype(np.float64), local.astype(np.float64)


def mixing_weights(global_feat_d, local_feats_rd, *, tau: float = 1.0, uniqueness: bool = True) -> np.ndarray:
    """Per-region weight ``w_i`` of the global feature (paper eqs. 3-5).

    Shape:
        ``global_feat_d`` (d,), ``local_feats_rd`` (R, d) -> (R,) float64 summing to 1.
    """
    if not tau > 0:
        raise ValueError(f"tau: expected a positive temperature, got {tau}")
    g, local = _check_embeddings(global_feat_d, local_feats_rd)
    r = local.shape[0]
    if r == 0:
        return np.zeros(0)
    phi = cosine(local, g[None])[:, 0]
    logits = phi
    if uniqueness:
        sim = cosine(local, local)
        phibar = (sim.sum(axis=1) - np.diag(sim)) / r
        logits = phi + phibar
    z = logits / tau
    z = np.exp(z - z.max())
    return z / z.sum()


def region_features(
    global_feat_d, local_feats_rd, *, tau: float = 1.0, uniqueness: bool = True, mode: str = "full"
) -> np.ndarray:
    """Unit-length pixel-aligned feature ``f_P_i`` of each region (paper eq. 6).

    ``mode="global"`` gives every region ``f_G`` (``w_i = 1``), ``mode="local"`` its own
    ``f_L_i`` (``w_i = 0``); ``"full"`` mixes them with the weights of eqs. 3-5.

    Shape:
        (d,), (R, d) -> (R, d) float32.
    """
    check_mode(mode)
    g, local = _check_embeddings(global_feat_d, local_feats_rd)
    if mode == "full":
        w = mixing_weights(g, local, tau=tau, uniqueness=uniqueness)[:, None]
    else:
        w = np.full((local.shape[0], 1), 1.0 if mode == "global" else 0.0)
    return _unit(w * _unit(g)[None] + (1.0 - w) * _unit(local)).astype(np.float32)


def _check_masks(masks_rhw, num_regions: int, image_hw: tuple[int, int] | None) -> np.ndarray:
    masks = as_array("masks_rhw", masks_rhw, shape=(num_regions, None, None), kinds="biu")
    if masks.dtype != bool:
        if masks.size and (masks.min() < 0 or masks.max() > 1):
            raise ValueError("masks_rhw: expected boolean masks (or 0/1 integers)")
        masks = masks.astype(bool)
    if image_hw is not None and masks.shape[1:] != tuple(image_hw):
        raise ShapeError(f"masks_rhw: expected masks of the image's size {tuple(image_hw)}, got {masks.shape[1:]}")
    return masks


def pixel_aligned_palette(
    global_feat_d,
    local_feats_rd,
    masks_rhw,
    *,
    tau: float = 1.0,
    uniqueness: bool = True,
    image_hw: tuple[int, int] | None = None,
    mode: str = "full",
) -> PixelFeatures:
    """Pixel-aligned features of a frame in palette form (see the module docstring).

    Args:
        global_feat_d: embedding of the whole image.
        local_feats_rd: embedding of each mask's crop, in mask order.
        masks_rhw: boolean region masks.
        tau: softmax temperature of eq. 5.
        uniqueness: include the ``phibar`` term of eq. 4.
        image_hw: if given, the masks must have this size.
        mode: ``"full"``, ``"global"`` or ``"local"`` (see :func:`region_features`).

    Shape:
        (d,), (R, d), (R, H, W) -> :class:`PixelFeatures` with palette (P, d), index (H, W).
    """
    check_mode(mode)
    g, local = _check_embeddings(global_feat_d, local_feats_rd)
    masks = _check_masks(masks_rhw, local.shape[0], image_hw)
    r, h, w = masks.shape
    d = g.shape[0]
    index = np.full(h * w, -1, dtype=np.int32)
    if r == 0:
        return PixelFeatures(np.zeros((0, d), np.float32), index.reshape(h, w))
    f_p = region_features(g, local, tau=tau, uniqueness=uniqueness, mode=mode).astype(np.float64)
    # A pixel's feature depends only on the set of masks covering it: pack that set into
    # bits per pixel (mask 0 the most significant) and find the distinct sets, in ascending
    # order of their packed bits.
    if r <= 64:
        codes = _mask_set_codes(masks.reshape(r, h * w))
        uniq = np.unique(codes)
        inverse = np.searchsorted(uniq, codes)
        members = ((uniq[:, None] >> (63 - np.arange(r, dtype=np.uint64))) & np.uint64(1)).astype(np.float64)  # (U, R)
    else:
        codes = np.ascontiguousarray(np.packbits(masks.reshape(r, h * w), axis=0).T)  # (HW, ceil(R/8))
        _, first, inverse = _unique_rows(codes)
        members = np.unpackbits(codes[first], axis=1, count=r).astype(np.float64)  # (U, R)
    inverse = inverse.ravel()
    covered = members.any(axis=1)
    palette = _unit(members[covered] @ f_p).astype(np.float32)
    remap = np.full(len(members), -1, dtype=np.int32)
    remap[covered] = np.arange(int(covered.sum()), dtype=np.int32)
    index[:] = remap[inverse]
    return PixelFeatures(palette, index.reshape(h, w))


def pixel_aligned_features(
    global_feat_d, local_feats_rd, masks_rhw, *, tau: float = 1.0, uniqueness: bool = True
) -> np.ndarray:
    """Dense pixel-aligned features (paper eqs. 3-6); see :func:`pixel_aligned_palette`.

    Shape:
        (d,), (R, d), (R, H, W) -> ``feats_hwd`` (H, W, d) float32; zero where no mask.
    """
    return pixel_aligned_palette(global_feat_d, local_feats_rd, masks_rhw, tau=tau, uniqueness=uniqueness).dense()


def mask_bboxes(masks_rhw) -> np.ndarray:
    """Tight bounding box of each mask as ``[row0, col0, row1, col1)`` (end exclusive).

    Raises ``ValueError`` for an empty mask (it has no box).

    Shape:
        (R, H, W) -> (R, 4) int64.
    """
    masks = as_array("masks_rhw", masks_rhw, shape=(None, None, None), kinds="biu").astype(bool)
    rows = masks.any(axis=2)
    cols = masks.any(axis=1)
    empty = ~rows.any(axis=1)
    if empty.any():
        raise ValueError(f"masks_rhw: expected non-empty masks, masks {np.flatnonzero(empty).tolist()} are empty")
    h, w = masks.shape[1:]
    r0 = rows.argmax(axis=1)
    r1 = h - rows[:, ::-1].argmax(axis=1)
    c0 = cols.argmax(axis=1)
    c1 = w - cols[:, ::-1].argmax(axis=1)
    return np.stack([r0, c0, r1, c1], axis=1).astype(np.int64)


def crop_masks(image_hw3: np.ndarray, masks_rhw) -> list[np.ndarray]:
    """Tight bounding-box crop of the image for each mask (no padding, no background masking).

    Shape:
        ``image_hw3`` (H, W, 3), ``masks_rhw`` (R, H, W) -> R arrays (h_i, w_i, 3) (views).
    """
    img = as_array("image_hw3", image_hw3, shape=(None, None, 3))
    boxes = mask_bboxes(masks_rhw)
    if np.asarray(masks_rhw).shape[1:] != img.shape[:2]:
        raise ShapeError(f"masks_rhw: expected masks of the image's size {img.shape[:2]}, got {np.asarray(masks_rhw).shape[1:]}")
    return [img[r0:r1, c0:c1] for r0, c0, r1, c1 in boxes]
