"""The embedded image tower: a small CNN mapping image crops into a text-embedding space.

The network is trained LiT-style (:mod:`tower_training.training`): the text tower is
frozen and the image tower learns to put a crop of an object next to the text embeddings of
its name and descriptions. At run time the tower runs through onnxruntime; torch is only
needed to train or export.

Preprocessing (the same for training and inference): the crop is padded to a square with
its mean colour (keeping the aspect ratio a tight mask box gives), resized to
``input_size`` with area interpolation, scaled to [0, 1] and normalised per channel with
fixed mean/std.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from collections import OrderedDict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from conceptfusion.perception.encoders import check_images, check_texts, embed_in_batches, onnx_session_options
from conceptfusion.errors import MissingDependencyError

__all__ = ["TowerConfig", "SHIPPED_TOWER_DIR", "SHIPPED_TOWER_V2_DIR", "NORMALISED_LEVELS", "square_crops", "preprocess",
           "build_tower", "export_tower_onnx", "EmbeddedEncoder"]

SHIPPED_TOWER_DIR = Path(__file__).resolve().parents[1] / "data" / "embedded_tower"
"""The shipped v1 tower (``embedded``): trained on the 7 kinds x 10 colours of the v1 world."""
SHIPPED_TOWER_V2_DIR = Path(__file__).resolve().parents[1] / "data" / "embedded_tower_v2"
"""The shipped v2 tower (``embedded-v2``): trained on the train split of the object library
(91 categories; see docs/model_card.md)."""
"""The trained tower that ships with the package (``make_encoder("embedded")``; see docs/model_card.md)."""

_MEAN = np.array([0.485, 0.456, 0.406], np.float32)
_STD = np.array([0.229, 0.224, 0.225], np.float32)
NORMALISED_LEVELS = (np.arange(256, dtype=np.uint8)[:, None].astype(np.float32) / 255.0 - _MEAN) / _STD
"""Normalised value of every uint8 level per channel, (256, 3) float32."""


@dataclass(frozen=True)
class TowerConfig:
    """Architecture of the image tower."""

    embed_dim: int = 384
    """Output dimension; equal to the text tower's."""
    input_size: int = 64
    """Side of the square input in pixels."""
    widths: tuple[int, ...] = (32, 64, 128, 256)
    """Channels of the four stages (each halves the resolution)."""
    blocks_per_stage: int = 2
    """Residual blocks per stage."""
    stem_stride: int = 1
    """Stride of the stem convolution (2 quarters the cost of every stage: the shipped tower
    uses it, so that training fits a CPU budget)."""


def preprocess(images: Sequence[np.ndarray], input_size: int) -> np.ndarray:
    """Crops to the tower's input tensor (see the module docstring): :func:`square_crops`, then
    each level replaced by its normalised value (:data:`NORMALISED_LEVELS`).

    Shape:
        n images (h_i, w_i, 3) uint8 -> (n, 3, S, S) float32.
    """
    small = square_crops(images, input_size)
    out = np.empty((len(small), 3, input_size, input_size), np.float32)
    for c in range(3):  # a table lookup per channel: the same float32 values as computing them per pixel
        out[:, c] = NORMALISED_LEVELS[:, c][small[..., c]]
    return out


def square_crops(images: Sequence[np.ndarray], input_size: int) -> np.ndarray:
    """The first half of :func:`preprocess`: each crop padded to a square with its mean colour
    and resized to ``input_size`` (area interpolation when shrinking), still uint8.

    Shape:
        n images (h_i, w_i, 3) uint8 -> (n, S, S, 3) uint8.
    """
    import cv2

    imgs = check_images(images)
    small = np.empty((len(imgs), input_size, input_size, 3), np.uint8)
    for i, img in enumerate(imgs):
        h, w = img.shape[:2]
        side = max(h, w)
        if h == w:
            square = img
        else:
            # The mean colour: an integer sum (exact, as the float64 sum of uint8 values is) over the count.
            fill = img.sum(axis=(0, 1), dtype=np.int64) / (h * w)
            square = np.empty((side, side, 3), np.uint8)
            square[:] = fill.astype(np.uint8)
            top, left = (side - h) // 2, (side - w) // 2
            square[top : top + h, left : left + w] = img
        interp = cv2.INTER_AREA if side > input_size else cv2.INTER_LINEAR
        small[i] = cv2.resize(square, (input_size, input_size), interpolation=interp)
    return small


def build_tower(config: TowerConfig = TowerConfig()):
    """A residual CNN: stem, four stages, global average pooling, linear projection, L2 norm.

    Returns a ``torch.nn.Module`` mapping (n, 3, S, S) to (n, embed_dim) unit vectors.
    """
    try:
        import torch
        from torch import nn
    except ImportError as exc:  # pragma: no cover - torch is installed by the install line
        raise MissingDependencyError(
            'training or exporting the image tower needs torch: pip install "conceptfusion-harness[torch]"'
        ) from exc

    class Block(nn.Module):
        def __init__(self, cin: int, cout: int, stride: int) -> None:
            super().__init__()
            self.conv1 = nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
            self.bn1 = nn.BatchNorm2d(cout)
            self.conv2 = nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
            self.bn2 = nn.BatchNorm2d(cout)
            self.skip = (
                nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))
                if stride != 1 or cin != cout
                else nn.Identity()
            )

        def forward(self, x):
            y = torch.relu(self.bn1(self.conv1(x)))
            return torch.relu(self.bn2(self.conv2(y)) + self.skip(x))

    class Tower(nn.Module):
        def __init__(self, cfg: TowerConfig) -> None:
            super().__init__()
            layers = [nn.Conv2d(3, cfg.widths[0], 3, cfg.stem_stride, 1, bias=False), nn.BatchNorm2d(cfg.widths[0]), nn.ReLU()]
            cin = cfg.widths[0]
            for cout in cfg.widths:
                for b in range(cfg.blocks_per_stage):
                    layers.append(Block(cin, cout, 2 if b == 0 else 1))
                    cin = cout
            self.features = nn.Sequential(*layers)
            self.head = nn.Linear(cin, cfg.embed_dim)

        def forward(self, x):
            f = self.features(x).mean(dim=(2, 3))
            return nn.functional.normalize(self.head(f), dim=1)

    return Tower(config)


def export_tower_onnx(model, config: TowerConfig, out_dir: str | Path, *, metadata: dict | None = None) -> Path:
    """Write ``tower.onnx`` and ``tower.json`` (config + metadata) to ``out_dir``.

    The graph takes ``images`` (n, 3, S, S) float32 and returns ``embeddings`` (n, d).
    """
    import torch

    from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = model.eval()
    dummy = torch.zeros(2, 3, config.input_size, config.input_size)
    import io

    buf = io.BytesIO()
    with warnings.catch_warnings():  # the TorchScript exporter is deprecated but needs no onnxscript
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(
            model,
            (dummy,),
            buf,
            input_names=["images"],
            output_names=["embeddings"],
            dynamic_axes={"images": {0: "n"}, "embeddings": {0: "n"}},
            opset_version=17,
            dynamo=False,
        )
    atomic_write_bytes(out / "tower.onnx", buf.getvalue())
    info = {"config": asdict(config), **(metadata or {})}
    atomic_write_text(out / "tower.json", json.dumps(info, indent=2, sort_keys=True))
    return out / "tower.onnx"


class EmbeddedEncoder:
    """The default offline encoder: the embedded image tower (onnxruntime) + a text tower.

    Images already embedded are remembered (an exact cache keyed by their pixels and size): an
    unchanged crop in the next frame, or the same crop twice in one call, is not run again. The
    tower's output for an image does not depend on the other images of its batch nor on the
    thread count, so the cache never changes a result.

    Args:
        tower_dir: folder with ``tower.onnx`` and ``tower.json``.
        text_encoder: the frozen text tower the image tower was aligned to (anything with
            ``encode_text`` and ``dim``).
        batch_size: crops per onnxruntime call.
        threads: onnxruntime intra-op threads (``None``: ``$CF_THREADS``, else 2); they sleep
            rather than spin between operators, so that a busy machine does not lose cores to
            waiting. Embeddings are bit-identical for any count.
        cache_size: images whose embedding is remembered (least recently used go first; 0: none).
    """

    def __init__(self, tower_dir: str | Path, text_encoder, *, batch_size: int = 64, threads: int | None = None,
                 cache_size: int = 4096) -> None:
        import onnxruntime as ort

        for name, value, low in (("batch_size", batch_size, 1), ("cache_size", cache_size, 0)):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
        d = Path(tower_dir)
        onnx_path, info_path = d / "tower.onnx", d / "tower.json"
        for p in (onnx_path, info_path):
            if not p.is_file():
                raise FileNotFoundError(f"embedded image tower: expected {p.name} in {d}, not found")
        try:
            info = json.loads(info_path.read_text())
            self.config = TowerConfig(**{**info["config"], "widths": tuple(info["config"]["widths"])})
        except (ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{info_path}: expected the tower's JSON config, could not read it: {exc}") from exc
        opts = onnx_session_options(threads)
        try:
            self._session = ort.InferenceSession(str(onnx_path), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types
            raise ValueError(f"{onnx_path}: not a loadable ONNX graph: {exc}") from exc
        out_dim = self._session.get_outputs()[0].shape[-1]
        if out_dim != self.config.embed_dim or text_encoder.dim != self.config.embed_dim:
            raise ValueError(
                f"embedded image tower: expected output size {self.config.embed_dim} matching the text "
                f"tower, got graph output {out_dim} and text tower {text_encoder.dim}"
            )
        self._text = text_encoder
        self._batch = int(batch_size)
        self._cache: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self._cache_size = int(cache_size)
        self.info = info

    @property
    def dim(self) -> int:
        return self.config.embed_dim

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Unit embeddings of RGB images; each distinct image not in the cache is run once.

        Shape:
            n images (h_i, w_i, 3) uint8 -> (n, d) float32.
        """
        imgs = check_images(images)
        if not self._cache_size:
            return self._run(imgs)
        keys = [_image_key(img) for img in imgs]
        todo: dict[tuple, int] = {}
        for key in keys:
            if key not in self._cache and key not in todo:
                todo[key] = len(todo)
        fresh = self._run([imgs[keys.index(key)] for key in todo]) if todo else None
        out = np.empty((len(imgs), self.dim), np.float32)
        for i, key in enumerate(keys):
            out[i] = fresh[todo[key]] if key in todo else self._cache[key]
        for key in keys:  # most recently used last
            if key in todo:
                self._cache[key] = fresh[todo[key]].copy()
            else:
                self._cache.move_to_end(key)
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return out

    def _run(self, imgs: list[np.ndarray]) -> np.ndarray:
        x = preprocess(imgs, self.config.input_size)
        return embed_in_batches(x, self._batch, self.dim, lambda batch: self._session.run(None, {"images": batch})[0])

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        return np.asarray(self._text.encode_text(check_texts(texts)), np.float32)


def _image_key(img: np.ndarray) -> tuple:
    """Cache key of one image: its size and a 160-bit digest of its pixels."""
    return img.shape, hashlib.blake2b(np.ascontiguousarray(img).data, digest_size=20).digest()
