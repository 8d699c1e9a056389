"""A user encoder behind a checking wrapper: what :func:`~conceptfusion.perception.registry.register_encoder`
hands the harness, so a wrong shape, a NaN or a vector off the unit sphere is refused at the call
that returned it, naming the encoder, the method, what was expected and what arrived, instead of
surfacing as a bad map many steps later.

The inputs are checked as the built-in encoders check theirs (a list of non-empty strings; of
(h, w, 3) uint8 images), so a user encoder sees only well-formed batches. Every answer is
checked: one norm per row costs far less than the embedding itself. Attributes the
wrapper does not define (``info`` with calibrated score floors, ``encode_audio``, ...) are the
wrapped encoder's, unchecked.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from conceptfusion.errors import EncoderOutputError
from conceptfusion.perception.encoders import check_images, check_texts

__all__ = ["UNIT_NORM_TOLERANCE", "CheckedTextEncoder", "CheckedEncoder", "checked_encoder", "check_embeddings"]

UNIT_NORM_TOLERANCE = 1e-3
"""How far a row's L2 norm may be from 1 (``|norm - 1| <= UNIT_NORM_TOLERANCE``)."""


def check_embeddings(name: str, method: str, out, n: int, dim: int, what: str) -> np.ndarray:
    """``out`` as float32 once it is ``n`` finite unit rows of ``dim`` numbers.

    Args:
        name: the encoder's registry name (for messages).
        method: ``"encode_text"`` or ``"encode_image"`` (for messages).
        out: what the method returned.
        n: how many inputs it was given.
        dim: the encoder's ``dim``.
        what: one input in words (``"text"``, ``"image"``).

    Shape:
        (n, dim) floating -> (n, dim) float32.

    Raises:
        EncoderOutputError: not a numpy array of floats, another shape, a NaN or inf, or a row
            whose norm is off by more than :data:`UNIT_NORM_TOLERANCE`.
    """
    where = f"encoder {name!r}: {method}"
    if not isinstance(out, np.ndarray):
        hint = " (convert it: .detach().cpu().numpy())" if hasattr(out, "detach") else ""
        raise EncoderOutputError(f"{where} returned {type(out).__name__}, expected a numpy array of shape ({n}, {dim}){hint}")
    if out.shape != (n, dim):
        raise EncoderOutputError(f"{where} returned shape {tuple(out.shape)}, expected ({n}, {dim}) (one row per {what}, dim {dim})")
    if out.dtype.kind != "f":
        raise EncoderOutputError(f"{where} returned dtype {out.dtype}, expected floating point (float32)")
    bad = ~np.isfinite(out)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        kind = "NaN" if np.isnan(out[row]).any() else "inf"
        raise EncoderOutputError(f"{where} returned {kind} in row {row} ({int(bad.any(axis=1).sum())} of {n} rows not finite), "
                                 "expected finite values")
    norms = np.linalg.norm(out.astype(np.float64, copy=False), axis=1)
    off = np.abs(norms - 1.0) > UNIT_NORM_TOLERANCE
    if off.any():
        row = int(np.argmax(off))
        raise EncoderOutputError(f"{where} row {row} has norm {norms[row]:.4g}, expected unit vectors "
                                 f"(|norm - 1| <= {UNIT_NORM_TOLERANCE:g}; scale each row by its norm)")
    return out.astype(np.float32, copy=False)


class CheckedTextEncoder:
    """A text encoder whose ``encode_text`` answers are checked (:func:`check_embeddings`).

    Args:
        name: the registry name (for messages).
        encoder: the wrapped encoder (``dim``, ``encode_text``).
    """

    def __init__(self, name: str, encoder) -> None:
        self._name, self._inner = name, encoder

    @property
    def name(self) -> str:
        """The registry name the encoder was registered under."""
        return self._name

    @property
    def wrapped(self):
        """The user's encoder itself."""
        return self._inner

    @property
    def dim(self) -> int:
        return int(self._inner.dim)

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """The wrapped encoder's text embeddings, checked. Shape: (n,) -> (n, dim) float32 unit rows."""
        texts = check_texts(texts)
        return check_embeddings(self._name, "encode_text", self._inner.encode_text(texts), len(texts), self.dim, "text")

    def __getattr__(self, attr: str):
        if attr.startswith("__") or attr in ("_name", "_inner"):
            raise AttributeError(attr)
        return getattr(self._inner, attr)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._name!r}, {self._inner!r})"


class CheckedEncoder(CheckedTextEncoder):
    """An image-and-text encoder whose answers are checked (:func:`check_embeddings`)."""

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """The wrapped encoder's image embeddings, checked. Shape: n (h, w, 3) uint8 -> (n, dim) float32 unit rows."""
        images = check_images(images)
        return check_embeddings(self._name, "encode_image", self._inner.encode_image(images), len(images), self.dim, "image")


def checked_encoder(name: str, encoder) -> CheckedTextEncoder:
    """``encoder`` behind the checking wrapper: :class:`CheckedEncoder` when it has
    ``encode_image``, else :class:`CheckedTextEncoder` (text only, as code asks with ``hasattr``).

    Raises:
        TypeError: ``encoder`` has no callable ``encode_text`` or no integer ``dim`` >= 1 (what a
            factory built, named).
    """
    if isinstance(encoder, CheckedTextEncoder):
        return encoder
    missing = [m for m in ("encode_text",) if not callable(getattr(encoder, m, None))]
    if missing:
        raise TypeError(f"encoder {name!r}: the factory built {type(encoder).__name__}, expected an object with "
                        "encode_text(texts) -> (n, dim), encode_image(images) -> (n, dim) (optional) and dim; "
                        f"missing {', '.join(missing)}")
    dim = getattr(encoder, "dim", None)
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1:
        raise TypeError(f"encoder {name!r}: the factory built {type(encoder).__name__} whose dim is {dim!r}, "
                        "expected an int >= 1 (the embedding dimension)")
    if callable(getattr(encoder, "encode_image", None)):
        return CheckedEncoder(name, encoder)
    return CheckedTextEncoder(name, encoder)
