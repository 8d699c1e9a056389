"""CLIP through Hugging Face ``transformers``, with CLIP's image preprocessing in numpy.

:class:`HFClipEncoder` loads a checkpoint from a hub id (``openai/clip-vit-base-patch32``) or
from a local folder written by ``save_pretrained`` (then nothing is looked up online:
``local_files_only``). Model families that share CLIP's API (``get_image_features``,
``get_text_features``, a tokenizer and a ``preprocessor_config.json``) load the same way:

- ``clip``: OpenAI CLIP and OpenCLIP/LAION checkpoints converted to the ``transformers``
  format (``openai/clip-vit-*``, ``laion/CLIP-ViT-*``). English.
- ``altclip``: ``BAAI/AltCLIP`` (English, Chinese) and ``BAAI/AltCLIP-m9`` (nine languages),
  an XLM-R text tower distilled into CLIP's space: the multilingual option.
- ``chinese_clip``: ``OFA-Sys/chinese-clip-*``. Chinese.

Multilingual checkpoints whose text tower lives outside ``transformers`` (M-CLIP, OpenCLIP's
``xlm-roberta`` models) and SigLIP (different pooling and padding) are not supported.

**Preprocessing** (:func:`clip_preprocess`) reproduces CLIP's image processor without PIL or
torchvision: resize so the shortest side equals ``size["shortest_edge"]`` (the other side
``int(s * long / short)``) with a separable, antialiased bicubic filter computed the way PIL
does (two passes, rounded to uint8 after each), centre-crop to ``crop_size``, scale by 1/255
and normalise with the checkpoint's ``image_mean``/``image_std``. The settings come from the
checkpoint's ``preprocessor_config.json``; without one, OpenAI CLIP's values at the vision
tower's ``image_size``.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from conceptfusion.perception.encoders import check_images, check_texts, embed_in_batches, unit_rows
from conceptfusion.errors import CheckpointError, MissingDependencyError

__all__ = ["ClipPreprocess", "clip_preprocess", "read_preprocess_config", "HFClipConfig", "HFClipEncoder", "SUPPORTED_MODEL_TYPES"]

logger = logging.getLogger(__name__)

_EXTRA = 'pip install "conceptfusion-harness[perception]"'

SUPPORTED_MODEL_TYPES = ("clip", "altclip", "chinese_clip")
"""``config.json`` ``model_type`` values :class:`HFClipEncoder` accepts."""

OPENAI_CLIP_MEAN = (0.48145466, 0.4578275, 0.40821073)
OPENAI_CLIP_STD = (0.26862954, 0.26130258, 0.27577711)

_WEIGHT_FILES = ("model.safetensors", "model.safetensors.index.json", "pytorch_model.bin", "pytorch_model.bin.index.json")


@dataclass(frozen=True)
class ClipPreprocess:
    """Image preprocessing settings of a CLIP-family checkpoint."""

    crop_hw: tuple[int, int]
    """Height and width of the network input (after the crop)."""
    shortest_edge: int | None = None
    """Resize so the shorter side has this length, keeping the aspect ratio; ``None``: see ``resize_hw``."""
    resize_hw: tuple[int, int] | None = None
    """Resize to exactly this size (used when ``shortest_edge`` is ``None``)."""
    center_crop: bool = True
    """Centre-crop to ``crop_hw`` after resizing."""
    mean: tuple[float, float, float] = OPENAI_CLIP_MEAN
    """Per-channel mean (RGB) subtracted after scaling to [0, 1]."""
    std: tuple[float, float, float] = OPENAI_CLIP_STD
    """Per-channel standard deviation (RGB) divided by."""
    resample: str = "bicubic"
    """``"bicubic"`` or ``"bilinear"`` (PIL's filters)."""

    def __post_init__(self) -> None:
        if self.shortest_edge is None and self.resize_hw is None:
            raise ValueError("ClipPreprocess: expected shortest_edge or resize_hw, got neither")
        if self.resample not in _FILTERS:
            raise ValueError(f"resample: expected one of {sorted(_FILTERS)}, got {self.resample!r}")
        if len(self.mean) != 3 or len(self.std) != 3 or min(self.std) <= 0:
            raise ValueError(f"mean/std: expected three values each, std > 0, got {self.mean} / {self.std}")


def _cubic(x: np.ndarray) -> np.ndarray:
    a = -0.5
    x = np.abs(x)
    return np.where(
        x < 1.0,
        ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0,
        np.where(x < 2.0, (((x - 5.0) * x + 8.0) * x - 4.0) * a, 0.0),
    )


def _triangle(x: np.ndarray) -> np.ndarray:
    return np.maximum(1.0 - np.abs(x), 0.0)


_FILTERS = {"bicubic": (_cubic, 2.0), "bilinear": (_triangle, 1.0)}
_PIL_RESAMPLE = {3: "bicubic", 2: "bilinear"}


def _resample_matrix(n_in: int, n_out: int, resample: str) -> np.ndarray:
    """(n_out, n_in) weights of PIL's antialiased resampling along one axis."""
    kernel, support = _FILTERS[resample]
    scale = n_in / n_out
    filterscale = max(scale, 1.0)
    support = support * filterscale
    centers = (np.arange(n_out) + 0.5) * scale
    lo = np.maximum((centers - support + 0.5).astype(np.int64), 0)
    hi = np.minimum((centers + support + 0.5).astype(np.int64), n_in)
    src = np.arange(n_in)[None, :]
    w = kernel((src - centers[:, None] + 0.5) / filterscale)
    w = np.where((src >= lo[:, None]) & (src < hi[:, None]), w, 0.0)
    total = w.sum(axis=1, keepdims=True)
    return w / np.where(total == 0.0, 1.0, total)


def _resize(img_hw3: np.ndarray, out_h: int, out_w: int, resample: str) -> np.ndarray:
    """PIL-style resize of a uint8 image: horizontal pass, round, vertical pass, round."""
    x = img_hw3
    h, w = x.shape[:2]
    if out_w != w:
        x = np.clip(np.rint(np.einsum("ow,hwc->hoc", _resample_matrix(w, out_w, resample), x.astype(np.float64))), 0, 255)
    if out_h != h:
        x = np.clip(np.rint(np.einsum("oh,hwc->owc", _resample_matrix(h, out_h, resample), x.astype(np.float64))), 0, 255)
    return x.astype(np.uint8)


def clip_preprocess(images: Sequence[np.ndarray], settings: ClipPreprocess) -> np.ndarray:
    """RGB images to CLIP's input tensor (see the module docstring).

    Shape:
        n images (h_i, w_i, 3) uint8 -> (n, 3, crop_h, crop_w) float32.
    """
    imgs = check_images(images)
    ch, cw = settings.crop_hw
    mean = np.asarray(settings.mean, np.float32)
    std = np.asarray(settings.std, np.float32)
    out = np.empty((len(imgs), 3, ch, cw), np.float32)
    for i, img in enumerate(imgs):
        h, w = img.shape[:2]
        if settings.shortest_edge is not None:
            s = settings.shortest_edge
            rh, rw = (s, int(s * w / h)) if h <= w else (int(s * h / w), s)
        else:
            rh, rw = settings.resize_hw
        x = _resize(img, rh, rw, settings.resample)
        if settings.center_crop:
            x = _center_crop(x, ch, cw)
        elif x.shape[:2] != (ch, cw):
            raise CheckpointError(f"preprocessing: resized images are {x.shape[:2]} but the model expects {(ch, cw)} and cropping is off")
        out[i] = ((x.astype(np.float32) / 255.0 - mean) / std).transpose(2, 0, 1)
    return out


def _center_crop(x: np.ndarray, ch: int, cw: int) -> np.ndarray:
    h, w = x.shape[:2]
    if h < ch or w < cw:  # pad with zeros around, as the image processor does
        padded = np.zeros((max(h, ch), max(w, cw), 3), x.dtype)
        top, left = (padded.shape[0] - h) // 2, (padded.shape[1] - w) // 2
        padded[top : top + h, left : left + w] = x
        x, h, w = padded, padded.shape[0], padded.shape[1]
    top, left = (h - ch) // 2, (w - cw) // 2
    return x[top : top + ch, left : left + cw]


def _hw(value, name: str) -> tuple[int, int]:
    if isinstance(value, int):
        return (value, value)
    if isinstance(value, dict) and "height" in value and "width" in value:
        return (int(value["height"]), int(value["width"]))
    raise CheckpointError(f"preprocessor config: expected {name} as an int or {{height, width}}, got {value!r}")


def read_preprocess_config(config: dict | None, image_size: int) -> ClipPreprocess:
    """Settings from a ``preprocessor_config.json`` dict (``None``: OpenAI CLIP's at ``image_size``)."""
    if config is None:
        return ClipPreprocess(crop_hw=(image_size, image_size), shortest_edge=image_size)
    size = config.get("size", image_size)
    shortest, resize_hw = None, None
    if isinstance(size, dict) and "shortest_edge" in size:
        shortest = int(size["shortest_edge"])
    elif isinstance(size, int) and config.get("do_center_crop", True):
        shortest = size  # old-style configs: an int size means the shortest edge
    else:
        resize_hw = _hw(size, "size")
    center_crop = bool(config.get("do_center_crop", True))
    crop_hw = _hw(config.get("crop_size", image_size), "crop_size") if center_crop else (resize_hw or (shortest, shortest))
    resample = _PIL_RESAMPLE.get(int(config.get("resample", 3)))
    if resample is None:
        raise CheckpointError(f"preprocessor config: expected resample 2 (bilinear) or 3 (bicubic), got {config.get('resample')!r}")
    return ClipPreprocess(
        crop_hw=crop_hw,
        shortest_edge=shortest,
        resize_hw=resize_hw,
        center_crop=center_crop,
        mean=tuple(float(v) for v in config.get("image_mean", OPENAI_CLIP_MEAN)),
        std=tuple(float(v) for v in config.get("image_std", OPENAI_CLIP_STD)),
        resample=resample,
    )


@dataclass(frozen=True)
class HFClipConfig:
    """How :class:`HFClipEncoder` runs."""

    batch_size: int = 32
    """Images or strings per forward pass."""
    device: str = "cpu"
    """Torch device."""
    max_length: int | None = None
    """Token limit for texts (longer ones are truncated); ``None``: the text tower's maximum."""

    def __post_init__(self) -> None:
        if not isinstance(self.batch_size, int) or self.batch_size < 1:
            raise ValueError(f"batch_size: expected an int >= 1, got {self.batch_size!r}")
        if self.max_length is not None and (not isinstance(self.max_length, int) or self.max_length < 3):
            raise ValueError(f"max_length: expected None or an int >= 3, got {self.max_length!r}")


def _import_transformers():
    try:
        import torch
        import transformers
    except ImportError as exc:
        raise MissingDependencyError(f"Hugging Face CLIP needs torch and transformers: {_EXTRA}") from exc
    return torch, transformers


def resolve_source(source: str | Path) -> tuple[str, bool]:
    """``(reference, is_local)``: a local folder if ``source`` is a Path, exists, or looks like a path.

    Raises:
        FileNotFoundError: ``source`` looks like a path but there is no folder there.
    """
    text = str(source)
    if not text.strip():
        raise ValueError("source: expected a hub id or a local folder, got an empty string")
    path = Path(text).expanduser()
    looks_local = isinstance(source, Path) or text.startswith(("/", ".", "~")) or path.exists()
    if not looks_local:
        return text, False
    if not path.is_dir():
        raise FileNotFoundError(
            f"{text}: no such folder; expected a CLIP checkpoint folder written by save_pretrained "
            f"(config.json, {_WEIGHT_FILES[0]} or {_WEIGHT_FILES[2]}, tokenizer files)"
        )
    return str(path), True


def check_checkpoint_folder(path: Path) -> None:
    """Raise :class:`CheckpointError` naming what a local checkpoint folder lacks."""
    if not (path / "config.json").is_file():
        raise CheckpointError(f"{path}: expected config.json of a CLIP checkpoint, not found")
    if not any((path / f).is_file() for f in _WEIGHT_FILES):
        raise CheckpointError(f"{path}: expected model weights ({' or '.join(_WEIGHT_FILES)}), none found")


class HFClipEncoder:
    """A CLIP-family model from ``transformers`` behind the :class:`~conceptfusion.perception.encoders.Encoder` protocol.

    Args:
        source: hub id (``"openai/clip-vit-base-patch32"``) or a local checkpoint folder.
        config: batch size, device, token limit.

    Raises:
        FileNotFoundError: ``source`` is a path and no folder is there.
        CheckpointError: files are missing or corrupt, weights do not match the config, or
            the model is not one of :data:`SUPPORTED_MODEL_TYPES`.
        MissingDependencyError: torch or transformers is not installed.
    """

    def __init__(self, source: str | Path, config: HFClipConfig = HFClipConfig()) -> None:
        torch, transformers = _import_transformers()
        ref, local = resolve_source(source)
        if local:
            check_checkpoint_folder(Path(ref))
        self.source = ref
        self.config = config
        where = f"{ref} ({'local folder' if local else 'hub id'})"
        if not local and os.environ.get("HF_HUB_OFFLINE", "").lower() in ("1", "true", "yes", "on"):
            where += " [downloads are off: HF_HUB_OFFLINE is set, so only the local cache is searched]"
        try:
            model_config = transformers.AutoConfig.from_pretrained(ref, local_files_only=local)
        except Exception as exc:  # transformers raises OSError, ValueError, JSON errors...
            raise CheckpointError(f"{where}: could not read config.json of a CLIP checkpoint: {exc}") from exc
        if model_config.model_type not in SUPPORTED_MODEL_TYPES:
            raise CheckpointError(
                f"{where}: expected a CLIP-family checkpoint (model_type one of {SUPPORTED_MODEL_TYPES}), "
                f"got model_type {model_config.model_type!r}"
            )
        try:
            model, info = transformers.AutoModel.from_pretrained(ref, local_files_only=local, output_loading_info=True)
        except Exception as exc:
            raise CheckpointError(f"{where}: could not load the model weights (corrupt or incomplete?): {exc}") from exc
        missing = list(info.get("missing_keys", ())) + [str(k) for k in info.get("mismatched_keys", ())]
        if missing:
            raise CheckpointError(
                f"{where}: expected weights for every parameter of config.json, "
                f"{len(missing)} missing or mismatched (first: {missing[:3]})"
            )
        try:
            tokenizer = transformers.AutoTokenizer.from_pretrained(ref, local_files_only=local)
        except Exception as exc:
            raise CheckpointError(
                f"{where}: could not load the tokenizer; expected tokenizer.json or vocab.json + merges.txt: {exc}"
            ) from exc
        self._tokenizer = tokenizer
        self._model = model.eval().to(config.device)
        self._torch = torch
        vision = model_config.vision_config
        self.preprocess = read_preprocess_config(_read_preprocessor_json(ref, local), int(vision.image_size))
        if self.preprocess.crop_hw != (vision.image_size, vision.image_size):
            raise CheckpointError(
                f"{where}: preprocessor crop size {self.preprocess.crop_hw} does not match the vision tower's "
                f"image_size {vision.image_size}"
            )
        self._max_length = config.max_length or int(model_config.text_config.max_position_embeddings)
        self._dim = int(model_config.projection_dim)
        logger.info("loaded %s (%s, %d-d)", ref, model_config.model_type, self._dim)

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def max_length(self) -> int:
        """Token limit applied to texts."""
        return self._max_length

    @property
    def model(self):
        """The ``transformers`` model (eval mode, on ``config.device``)."""
        return self._model

    @property
    def tokenizer(self):
        """The ``transformers`` tokenizer of the checkpoint."""
        return self._tokenizer

    def tokenize(self, texts: Sequence[str]) -> dict[str, np.ndarray]:
        """Token ids and attention mask as the model sees them.

        Shape:
            n strings -> ``input_ids`` and ``attention_mask``, each (n, L) int64.
        """
        enc = self._tokenizer(
            check_texts(texts), padding=True, truncation=True, max_length=self._max_length, return_tensors="np"
        )
        return {"input_ids": enc["input_ids"].astype(np.int64), "attention_mask": enc["attention_mask"].astype(np.int64)}

    def _run(self, fn, **inputs) -> np.ndarray:
        torch = self._torch
        with torch.inference_mode():
            out = fn(**{k: torch.from_numpy(v).to(self.config.device) for k, v in inputs.items()})
        feats = out if isinstance(out, torch.Tensor) else out.pooler_output
        return unit_rows(feats.float().cpu().numpy())

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Embed RGB images.

        Shape:
            n images (h_i, w_i, 3) uint8 -> (n, d) float32, unit rows.
        """
        x = clip_preprocess(images, self.preprocess)
        return embed_in_batches(x, self.config.batch_size, self._dim,
                                lambda batch: self._run(self._model.get_image_features, pixel_values=batch))

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Embed non-empty strings.

        Shape:
            n strings -> (n, d) float32, unit rows.
        """
        return embed_in_batches(check_texts(texts), self.config.batch_size, self._dim,
                                lambda batch: self._run(self._model.get_text_features, **self.tokenize(batch)))


def _read_preprocessor_json(ref: str, local: bool) -> dict | None:
    """The checkpoint's ``preprocessor_config.json`` as a dict, or ``None`` if it has none."""
    if local:
        path = Path(ref) / "preprocessor_config.json"
        if not path.is_file():
            logger.info("%s has no preprocessor_config.json; using OpenAI CLIP's preprocessing", ref)
            return None
    else:
        try:
            from huggingface_hub import hf_hub_download

            path = Path(hf_hub_download(ref, "preprocessor_config.json"))
        except Exception as exc:  # not on the hub, offline and not cached...
            logger.warning("%s: no preprocessor_config.json (%s); using OpenAI CLIP's preprocessing", ref, exc)
            return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise CheckpointError(f"{path}: expected a JSON image-processor config, could not read it: {exc}") from exc
