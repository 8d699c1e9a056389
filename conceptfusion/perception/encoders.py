"""The encoder protocol, and a tiny deterministic encoder for tests and demos.

An encoder maps images and texts into one vector space where cosine similarity means
"same concept" (CLIP and its kin). Real encoders (the embedded image/text towers, Hugging
Face or ONNX CLIP) implement the same protocol.
"""

from __future__ import annotations

import hashlib
import os
import re
from typing import Callable, Protocol, Sequence, runtime_checkable

import numpy as np

from conceptfusion.errors import DtypeError, ShapeError

__all__ = ["Encoder", "ColorNameEncoder", "check_images", "check_texts", "unit_rows", "embed_in_batches", "COLOR_NAMES",
           "THREADS_ENV", "default_threads", "onnx_session_options"]


@runtime_checkable
class Encoder(Protocol):
    """Images and texts to unit vectors of one shared space."""

    @property
    def dim(self) -> int:
        """Embedding dimension ``d``."""
        ...

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Embed RGB images (each (h, w, 3) uint8, any size). Returns (n, d) float32, unit rows."""
        ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Embed non-empty strings. Returns (n, d) float32, unit rows."""
        ...


THREADS_ENV = "CF_THREADS"
"""Environment variable: how many threads an encoder's runtime may use in this process. The
harness's process backend sets it to each worker's share of the cores; unset, encoders use 2."""


def default_threads() -> int:
    """Intra-op threads for an encoder built without an explicit count: ``$CF_THREADS`` when
    set (``ValueError`` unless it is an integer >= 1), else 2."""
    raw = os.environ.get(THREADS_ENV)
    if raw is None or raw == "":
        return 2
    try:
        value = int(raw)
    except ValueError:
        value = 0
    if value < 1:
        raise ValueError(f"${THREADS_ENV}: expected an integer >= 1, got {raw!r}")
    return value


def onnx_session_options(threads: int | None):
    """onnxruntime session options for a CPU encoder: ``threads`` intra-op threads
    (``None``: :func:`default_threads`) that sleep rather than spin between operators (spinning
    threads burn the CPU that rendering and fusion need; results are the same either way), and
    warnings only."""
    import onnxruntime as ort

    if threads is None:
        threads = default_threads()
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads: expected an integer >= 1 or None, got {threads!r}")
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    opts.log_severity_level = 3
    return opts


def check_images(images: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Validate a batch of RGB images: each (h, w, 3) uint8 with h, w >= 1."""
    if isinstance(images, np.ndarray) and images.ndim == 3:
        raise ShapeError("images: expected a sequence of (h, w, 3) images or an (n, h, w, 3) array, got one (h, w, 3) image")
    out = []
    for i, img in enumerate(images):
        if not isinstance(img, np.ndarray):
            raise DtypeError(f"images[{i}]: expected a numpy array, got {type(img).__name__}")
        if img.dtype != np.uint8:
            raise DtypeError(f"images[{i}]: expected uint8 RGB, got {img.dtype}")
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
            raise ShapeError(f"images[{i}]: expected shape (h, w, 3) with h, w >= 1, got {img.shape}")
        out.append(img)
    return out


def unit_rows(x_nd) -> np.ndarray:
    """Each row scaled to unit length (computed in float64; all-zero rows stay zero), as float32.

    Shape:
        (n, d) -> (n, d) float32.
    """
    x = np.asarray(x_nd, np.float64)
    return (x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)).astype(np.float32)


def embed_in_batches(items: Sequence, batch_size: int, dim: int, embed: Callable[[Sequence], np.ndarray]) -> np.ndarray:
    """``embed`` run on consecutive slices of at most ``batch_size`` items, its rows stacked.

    Shape:
        n items -> (n, dim) float32 (``embed``: m items -> (m, dim)).
    """
    out = np.empty((len(items), dim), np.float32)
    for s in range(0, len(items), batch_size):
        out[s : s + batch_size] = embed(items[s : s + batch_size])
    return out


def check_texts(texts: Sequence[str]) -> list[str]:
    """Validate a batch of query strings: each a non-empty, non-blank ``str``."""
    if isinstance(texts, str):
        raise TypeError("texts: expected a sequence of strings, got a single str (wrap it in a list)")
    out = []
    for i, t in enumerate(texts):
        if not isinstance(t, str):
            raise TypeError(f"texts[{i}]: expected str, got {type(t).__name__}")
        if not t.strip():
            raise ValueError(f"texts[{i}]: expected a non-empty query, got {t!r}")
        out.append(t)
    return out


COLOR_NAMES: dict[str, tuple[int, int, int]] = {
    "red": (200, 30, 30),
    "green": (40, 160, 60),
    "blue": (30, 60, 200),
    "yellow": (230, 210, 40),
    "orange": (240, 130, 30),
    "purple": (130, 50, 160),
    "pink": (240, 140, 190),
    "brown": (120, 75, 40),
    "black": (20, 20, 20),
    "white": (240, 240, 240),
    "gray": (128, 128, 128),
}
"""Prototype colours the :class:`ColorNameEncoder` knows by name."""

_ALIASES = {"grey": "gray", "violet": "purple", "crimson": "red", "navy": "blue"}


class ColorNameEncoder:
    """A tiny, deterministic encoder whose shared space is "which basic colour".

    Images embed as a soft histogram of their pixels over the prototype colours of
    :data:`COLOR_NAMES` (softmax of negative RGB distance). Texts embed as the histogram of
    the colour words they contain; words it does not know hash to private directions, so a
    query with no colour word matches nothing in particular. Both go through one fixed
    random orthogonal map into ``dim`` dimensions. It needs no weights, so tests and demos
    exercise every part of the pipeline; it understands nothing but colour.

    Args:
        dim: embedding dimension (at least ``len(COLOR_NAMES) + 8``).
        sharpness: softmax sharpness over RGB distance (per 255 units).
        seed: seed of the fixed random map.
    """

    def __init__(self, dim: int = 32, *, sharpness: float = 12.0, seed: int = 0) -> None:
        k = len(COLOR_NAMES)
        if dim < k + 8:
            raise ValueError(f"dim: expected at least {k + 8}, got {dim}")
        self._dim = int(dim)
        self._sharpness = float(sharpness)
        q, _ = np.linalg.qr(np.random.default_rng(seed).standard_normal((dim, dim)))
        self._basis = q.astype(np.float64)  # rows: orthonormal directions
        self._protos = np.array(list(COLOR_NAMES.values()), np.float64) / 255.0
        self._names = list(COLOR_NAMES)

    @property
    def dim(self) -> int:
        return self._dim

    def _to_space(self, coeffs_nk: np.ndarray) -> np.ndarray:
        return unit_rows(coeffs_nk @ self._basis[: coeffs_nk.shape[1]])

    def color_histogram(self, image_hw3: np.ndarray) -> np.ndarray:
        """Soft histogram of an image's pixels over the prototype colours, (K,) summing to 1."""
        px = image_hw3.reshape(-1, 3).astype(np.float64) / 255.0
        if len(px) > 4096:  # a fixed subsample keeps large crops cheap and deterministic
            px = px[np.linspace(0, len(px) - 1, 4096).astype(int)]
        d = np.linalg.norm(px[:, None, :] - self._protos[None], axis=2)
        z = -self._sharpness * d
        p = np.exp(z - z.max(axis=1, keepdims=True))
        p /= p.sum(axis=1, keepdims=True)
        return p.mean(axis=0)

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        imgs = check_images(images)
        k = len(self._names)
        coeffs = np.zeros((len(imgs), self._dim))
        for i, img in enumerate(imgs):
            coeffs[i, :k] = self.color_histogram(img)
        return self._to_space(coeffs)

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        txts = check_texts(texts)
        k = len(self._names)
        coeffs = np.zeros((len(txts), self._dim))
        for i, t in enumerate(txts):
            words = [_ALIASES.get(w, w) for w in re.findall(r"[a-z]+", t.lower())]
            colors = [w for w in words if w in COLOR_NAMES]
            if colors:
                for c in colors:
                    coeffs[i, self._names.index(c)] += 1.0
            else:
                # Unknown words: a direction outside the colour subspace, fixed per text.
                h = int.from_bytes(hashlib.sha256(t.strip().lower().encode()).digest()[:4], "little")
                coeffs[i, k + h % (self._dim - k)] = 1.0
        return self._to_space(coeffs)
