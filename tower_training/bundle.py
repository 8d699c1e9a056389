"""A training bundle: everything the v2 tower's optimisation reads, in one file.

``python -m tower_training.train --world v2 --bundle FILE`` renders (or loads) the crops, encodes
the caption bank with the frozen text tower and writes them here; :mod:`tower_training.fit`
trains from the file alone. Reading it needs numpy, OpenCV and nothing of the simulator or the
text tower, so the optimisation can run on a machine that has torch and an accelerator but not
the project's simulation stack.

Contents (one ``.npz``, written atomically):

* the training crops, each a lossless WebP (:func:`encode_crops`), with their class index into
  the caption bank's classes;
* the caption bank: text embeddings, which captions each class has, each caption's weight;
* the model-selection set: the validation crops, each crop's true category among the library's
  names, and those names' text embeddings (:func:`tower_training.evaluate_v2.val_selection_inputs`);
* ``meta``: JSON with the data settings, the caption texts and kinds, the class and category
  names, the split summary, and the command that wrote it.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from conceptfusion.io_utils import atomic_write_bytes
from tower_training.training import CropSet

__all__ = ["Bundle", "encode_crops", "decode_crops", "save_bundle", "load_bundle", "file_sha256"]

_ARRAYS = ("train_images", "train_offsets", "train_labels", "captions_td", "positives_ct", "caption_weights_t",
           "val_images", "val_offsets", "val_truth", "names_td", "meta")


@dataclass(frozen=True)
class Bundle:
    """What the optimisation and its model selection read.

    Shape:
        ``train``: n crops with labels in [0, C); ``captions_td`` (T, d) unit rows;
        ``positives_ct`` (C, T) bool, at least one per class; ``caption_weights_t`` (T,);
        ``val_images`` m crops (h_i, w_i, 3) uint8; ``val_truth`` (m,) rows of ``names_td`` (K, d).
    """

    train: CropSet
    captions_td: np.ndarray
    positives_ct: np.ndarray
    caption_weights_t: np.ndarray
    val_images: list
    val_truth: np.ndarray
    names_td: np.ndarray
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        c, t = self.positives_ct.shape
        if self.captions_td.shape[0] != t or len(self.caption_weights_t) != t:
            raise ValueError(f"bundle: {t} captions in positives_ct, {self.captions_td.shape[0]} embeddings, "
                             f"{len(self.caption_weights_t)} weights")
        if len(self.train.labels) and (self.train.labels.min() < 0 or self.train.labels.max() >= c):
            raise ValueError(f"bundle: training labels must index the {c} classes of positives_ct, "
                             f"got {self.train.labels.min()}..{self.train.labels.max()}")
        if not self.positives_ct.any(axis=1).all():
            raise ValueError("bundle: every class needs at least one positive caption")
        if len(self.val_images) != len(self.val_truth):
            raise ValueError(f"bundle: {len(self.val_images)} validation crops but {len(self.val_truth)} labels")
        if len(self.val_truth) and (self.val_truth.min() < 0 or self.val_truth.max() >= len(self.names_td)):
            raise ValueError(f"bundle: validation labels must index the {len(self.names_td)} names")
        if self.names_td.shape[1:] != self.captions_td.shape[1:]:
            raise ValueError(f"bundle: name embeddings {self.names_td.shape} and caption embeddings "
                             f"{self.captions_td.shape} differ in dimension")


def encode_crops(images) -> tuple[np.ndarray, np.ndarray]:
    """Crops as lossless WebP images (exact pixels; about 70% of the bytes of PNG at its strongest
    compression on rendered crops), concatenated.

    Shape:
        n crops (h_i, w_i, 3) uint8 -> (bytes (B,) uint8, offsets (n + 1,) int64).
    """
    import cv2

    blobs = []
    for i, im in enumerate(images):
        if im.ndim != 3 or im.shape[2] != 3 or im.dtype != np.uint8:
            raise ValueError(f"crop {i}: expected an (h, w, 3) uint8 image, got {im.shape} {im.dtype}")
        ok, buf = cv2.imencode(".webp", np.ascontiguousarray(im), [cv2.IMWRITE_WEBP_QUALITY, 101])  # > 100: lossless
        if not ok:
            raise ValueError(f"crop {i}: WebP encoding failed")
        blobs.append(buf.reshape(-1))
    offsets = np.zeros(len(blobs) + 1, np.int64)
    offsets[1:] = np.cumsum([len(b) for b in blobs])
    data = np.concatenate(blobs) if blobs else np.zeros(0, np.uint8)
    return data, offsets


def decode_crops(data: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    """What :func:`encode_crops` wrote, as (h_i, w_i, 3) uint8 crops."""
    import cv2

    if offsets.ndim != 1 or len(offsets) < 1 or offsets[0] != 0 or offsets[-1] != len(data) or np.any(np.diff(offsets) <= 0):
        raise ValueError(f"crop offsets: expected increasing offsets from 0 to {len(data)}, got {offsets[:3]}..{offsets[-1:]}")
    out = []
    for i in range(len(offsets) - 1):
        im = cv2.imdecode(data[offsets[i]:offsets[i + 1]], cv2.IMREAD_UNCHANGED)
        if im is None or im.ndim != 3 or im.shape[2] != 3:
            raise ValueError(f"crop {i}: not a 3-channel WebP image")
        out.append(im)
    return out


def save_bundle(path: str | Path, bundle: Bundle) -> Path:
    """Write ``bundle`` to one ``.npz`` atomically; returns the path."""
    train_images, train_off = encode_crops(bundle.train.images)
    val_images, val_off = encode_crops(bundle.val_images)
    buf = io.BytesIO()
    np.savez(buf, train_images=train_images, train_offsets=train_off, train_labels=np.asarray(bundle.train.labels, np.int64),
             captions_td=np.asarray(bundle.captions_td, np.float32), positives_ct=np.asarray(bundle.positives_ct, bool),
             caption_weights_t=np.asarray(bundle.caption_weights_t, np.float32), val_images=val_images, val_offsets=val_off,
             val_truth=np.asarray(bundle.val_truth, np.int64), names_td=np.asarray(bundle.names_td, np.float32),
             meta=np.array(json.dumps(bundle.meta, sort_keys=True)))
    return atomic_write_bytes(path, buf.getvalue())


def load_bundle(path: str | Path) -> Bundle:
    """Read what :func:`save_bundle` wrote (errors name the file and the array)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"training bundle: expected a .npz file at {p}, not found")
    try:
        z = np.load(p, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{p}: not a training bundle (.npz): {exc}") from exc
    with z:
        missing = set(_ARRAYS) - set(z.files)
        if missing:
            raise ValueError(f"{p}: expected a training bundle, missing arrays {sorted(missing)}")
        try:
            train = CropSet(decode_crops(z["train_images"], z["train_offsets"]), z["train_labels"])
            val = decode_crops(z["val_images"], z["val_offsets"])
            return Bundle(train, z["captions_td"], z["positives_ct"], z["caption_weights_t"], val, z["val_truth"],
                          z["names_td"], json.loads(str(z["meta"])))
        except ValueError as exc:
            raise ValueError(f"{p}: {exc}") from exc


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes (a bundle's identity in the records of what was trained on it)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
