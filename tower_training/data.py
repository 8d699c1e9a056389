"""Labelled crops for training the embedded image tower, cut from labelled RGB-D views.

A view is an RGB-D frame with an instance segmentation and the name of each instance
(``"red mug"``); where the views come from (a simulator) is the caller's business. Each view
gives four kinds of crop (:data:`SOURCES`):

* ``gt``: the tight box of each visible object's ground-truth mask, widened on every side by
  a random fraction of its size (``pad_range``) - the crops the ground-truth proposer makes,
  with the looseness a real proposer adds;
* ``proposer``: the tight box of every proposer mask whose best ground-truth IoU is at least
  ``match_iou``, labelled with that object - the crops the tower will see at run time,
  under- and over-segmentations included;
* ``background``: proposer masks that overlap no object (IoU below ``background_iou`` with
  every one, and at most ``background_object_fraction`` of their pixels on objects),
  labelled :data:`BACKGROUND_CLASS` (table, floor) so that such crops do not land on an
  object's name;
* ``frame``: the whole view, labelled :data:`SCENE_CLASS` ("a table with objects"). The
  global embedding of the paper's mixing is compared with every region's, so it should
  describe the scene as a whole rather than one object.

Clutter gives partial occlusion for free. Crops larger than ``max_side`` are shrunk (area
interpolation, aspect kept) to bound memory: the tower sees 64x64 inputs anyway.

A :class:`CropData` stores the crops with their label, source, scene seed and view number,
and saves to / loads from one compressed ``.npz`` (written atomically).
"""

from __future__ import annotations

import io
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from conceptfusion.perception.features import mask_bboxes
from conceptfusion.io_utils import atomic_write_bytes

__all__ = [
    "ObjectClass",
    "BACKGROUND_CLASS",
    "SCENE_CLASS",
    "ROOM_BACKGROUND_CLASS",
    "ROOM_SCENE_CLASS",
    "SOURCES",
    "instance_classes",
    "CropConfig",
    "CropData",
    "crops_from_view",
    "build_crop_data",
    "default_cache_dir",
]

logger = logging.getLogger(__name__)


def default_cache_dir() -> str:
    """Where the training commands cache rendered crops: ``$XDG_CACHE_HOME/conceptfusion``
    (``~/.cache/conceptfusion`` when the variable is unset)."""
    return os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "conceptfusion")

SOURCES = ("gt", "proposer", "background", "frame")
"""Crop kinds, by the index stored in :attr:`CropData.sources`."""


@dataclass(frozen=True)
class ObjectClass:
    """A class the tower is trained on: a name and the phrases whose mean embedding is its target."""

    name: str
    """What a user types ("red mug")."""
    phrases: tuple[str, ...]
    """Name, article form and descriptions ("red mug", "a red mug", "a coffee mug", ...)."""
    category: str = ""
    """Object category ("mug"); empty for the background and scene classes."""
    color: str = ""
    """Colour word ("red"); empty for the background and scene classes."""


BACKGROUND_CLASS = ObjectClass("table or floor", ("a wooden table", "the floor", "a table top"))
"""Label of proposer masks that cover no object."""

SCENE_CLASS = ObjectClass("a table with objects", ("a table with objects", "objects on a table", "a tabletop scene"))
"""Label of whole-frame views (the global embedding)."""

ROOM_BACKGROUND_CLASS = ObjectClass("wall, floor or furniture", ("a wall", "the floor", "a piece of furniture"))
"""Label of proposer masks that cover no object in an apartment view (walls, floors, sofas, shelves)."""

ROOM_SCENE_CLASS = ObjectClass("a room of a home", ("a room of a home", "a room with furniture", "the inside of a house"))
"""Label of whole apartment views."""


def instance_classes(colors: Sequence[str], categories: Mapping[str, Sequence[str]]) -> list[ObjectClass]:
    """Every colour x category instance, sorted by category then colour.

    Args:
        colors: colour words ("red", ...).
        categories: category -> its descriptive phrases ("mug" -> ("a coffee mug", ...)).

    Returns:
        ``ObjectClass("red mug", ("red mug", "a red mug", *phrases), "mug", "red")`` for each pair.
    """
    if not colors or not categories:
        raise ValueError(f"expected at least one colour and one category, got {len(colors)} and {len(categories)}")
    out = []
    for cat in sorted(categories):
        for c in sorted(colors):
            name = f"{c} {cat}"
            out.append(ObjectClass(name, (name, f"a {name}") + tuple(categories[cat]), cat, c))
    return out


@dataclass(frozen=True)
class CropConfig:
    """How crops are cut from a view."""

    pad_range: tuple[float, float] = (0.0, 0.2)
    """Random widening of a ground-truth box on each side, as a fraction of its height/width."""
    min_area_px: int = 80
    """Objects (and proposer masks) with fewer visible pixels give no crop."""
    match_iou: float = 0.5
    """A proposer mask is labelled with the object it overlaps at least this much (IoU)."""
    background_iou: float = 0.1
    """A proposer mask with IoU below this with every object may be a background crop ..."""
    background_object_fraction: float = 0.05
    """... if at most this fraction of its pixels lie on objects."""
    max_background: int = 2
    """At most this many background crops per view (chosen at random)."""
    max_side: int = 96
    """Crops larger than this (either side) are shrunk to it, aspect kept."""
    frame_side: int = 128
    """Whole-frame crops are shrunk so their longer side is this."""

    def __post_init__(self) -> None:
        lo, hi = self.pad_range
        if not 0 <= lo <= hi:
            raise ValueError(f"pad_range: expected 0 <= lo <= hi, got {self.pad_range}")
        for name in ("match_iou", "background_iou", "background_object_fraction"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name}: expected a value in [0, 1], got {getattr(self, name)}")
        if self.min_area_px < 1 or self.max_side < 8 or self.frame_side < 8 or self.max_background < 0:
            raise ValueError("min_area_px >= 1, max_side >= 8, frame_side >= 8, max_background >= 0 expected")


@dataclass
class CropData:
    """Labelled crops.

    Shape:
        ``images``: n arrays (h_i, w_i, 3) uint8; ``labels``, ``sources``, ``seeds``,
        ``views`` (n,) int64: class index, index into :data:`SOURCES`, scene seed, view
        number (global over the build); ``class_names`` C strings.
    """

    images: list
    labels: np.ndarray
    sources: np.ndarray
    seeds: np.ndarray
    views: np.ndarray
    class_names: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.images)
        for name in ("labels", "sources", "seeds", "views"):
            arr = np.asarray(getattr(self, name), np.int64).reshape(-1)
            if len(arr) != n:
                raise ValueError(f"CropData.{name}: expected {n} entries (one per image), got {len(arr)}")
            setattr(self, name, arr)

    def __len__(self) -> int:
        return len(self.images)

    def subset(self, mask: np.ndarray) -> "CropData":
        """The crops where ``mask`` (n,) bool is true."""
        idx = np.flatnonzero(np.asarray(mask, bool))
        return CropData([self.images[i] for i in idx], self.labels[idx], self.sources[idx], self.seeds[idx],
                        self.views[idx], self.class_names)

    @classmethod
    def concat(cls, parts: Sequence["CropData"]) -> "CropData":
        """One set of the crops of ``parts``, in order; class names are the union (first
        appearance order) and each part's labels are re-indexed into it. View numbers are
        offset so that views of different parts stay distinct."""
        if not parts:
            raise ValueError("parts: expected at least one CropData")
        names: list[str] = []
        for p in parts:
            names += [n for n in p.class_names if n not in names]
        index = {n: i for i, n in enumerate(names)}
        images, labels, sources, seeds, views, offset = [], [], [], [], [], 0
        for p in parts:
            remap = np.array([index[n] for n in p.class_names], np.int64)
            images += list(p.images)
            labels.append(remap[p.labels] if len(p) else np.zeros(0, np.int64))
            sources.append(p.sources)
            seeds.append(p.seeds)
            views.append(p.views + offset)
            offset += int(p.views.max()) + 1 if len(p) else 0
        return cls(images, np.concatenate(labels), np.concatenate(sources), np.concatenate(seeds),
                   np.concatenate(views), tuple(names))

    def save(self, path: str | Path) -> Path:
        """Write one compressed ``.npz`` atomically (pixels concatenated, with per-crop shapes)."""
        shapes = np.array([im.shape[:2] for im in self.images], np.int64).reshape(-1, 2)
        pixels = np.concatenate([np.ascontiguousarray(im).reshape(-1) for im in self.images]) if self.images else np.zeros(0, np.uint8)
        buf = io.BytesIO()
        np.savez_compressed(buf, pixels=pixels.astype(np.uint8), shapes=shapes, labels=self.labels, sources=self.sources,
                            seeds=self.seeds, views=self.views, class_names=np.array(self.class_names, dtype=str))
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> "CropData":
        """Read what :meth:`save` wrote."""
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"crop data: expected a .npz file at {p}, not found")
        with np.load(p, allow_pickle=False) as z:
            missing = {"pixels", "shapes", "labels", "sources", "seeds", "views", "class_names"} - set(z.files)
            if missing:
                raise ValueError(f"{p}: expected a crop-data archive, missing arrays {sorted(missing)}")
            shapes = z["shapes"]
            pixels = z["pixels"]
            sizes = shapes[:, 0] * shapes[:, 1] * 3
            ends = np.cumsum(sizes)
            if len(ends) and ends[-1] != len(pixels):
                raise ValueError(f"{p}: pixel count {len(pixels)} does not match the crop shapes ({ends[-1]})")
            starts = ends - sizes
            images = [pixels[s:e].reshape(h, w, 3) for s, e, (h, w) in zip(starts, ends, shapes)]
            return cls(images, z["labels"], z["sources"], z["seeds"], z["views"], tuple(str(s) for s in z["class_names"]))


def _shrink(img: np.ndarray, side: int) -> np.ndarray:
    import cv2

    h, w = img.shape[:2]
    s = side / max(h, w)
    if s >= 1:
        return np.ascontiguousarray(img)
    return cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def _padded_box(box, pad: np.ndarray, h: int, w: int) -> tuple[int, int, int, int]:
    r0, c0, r1, c1 = (int(v) for v in box)
    bh, bw = r1 - r0, c1 - c0
    return (max(0, r0 - int(pad[0] * bh)), max(0, c0 - int(pad[1] * bw)),
            min(h, r1 + int(pad[2] * bh)), min(w, c1 + int(pad[3] * bw)))


def crops_from_view(
    rgb_hw3: np.ndarray,
    segmentation_hw: np.ndarray,
    object_labels: Sequence[int],
    rng: np.random.Generator,
    *,
    proposal_masks_rhw: np.ndarray | None = None,
    background_label: int | None = None,
    scene_label: int | None = None,
    config: CropConfig = CropConfig(),
) -> tuple[list[np.ndarray], list[int], list[int]]:
    """Cut the labelled crops of one view (see the module docstring).

    Args:
        rgb_hw3: the image.
        segmentation_hw: object index per pixel, -1 for no object.
        object_labels: class index of each object index (-1: give it no crop).
        rng: draws the box padding and the background crops kept.
        proposal_masks_rhw: the proposer's masks, or ``None`` for no ``proposer`` and
            ``background`` crops.
        background_label, scene_label: class indices of the background and scene classes,
            or ``None`` for no such crops.

    Returns:
        crops, their class labels and their source indices (into :data:`SOURCES`).

    Shape:
        (H, W, 3) uint8, (H, W) int, (O,), masks (R, H, W) bool -> n crops (h_i, w_i, 3).
    """
    rgb = np.asarray(rgb_hw3)
    seg = np.asarray(segmentation_hw)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"rgb_hw3: expected (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
    if seg.shape != rgb.shape[:2]:
        raise ValueError(f"segmentation_hw: expected the image's size {rgb.shape[:2]}, got {seg.shape}")
    labels_o = np.asarray(object_labels, np.int64).reshape(-1)
    if seg.size and seg.max() >= len(labels_o):
        raise ValueError(f"object_labels: segmentation indexes object {seg.max()}, but only {len(labels_o)} labels given")
    h, w = seg.shape
    crops, labels, sources = [], [], []

    ids, counts = np.unique(seg[seg >= 0], return_counts=True)
    keep = (counts >= config.min_area_px) & (labels_o[ids] >= 0) if len(ids) else np.zeros(0, bool)
    ids = ids[keep]
    gt = seg[None] == ids[:, None, None] if len(ids) else np.zeros((0, h, w), bool)
    if len(ids):
        for obj, box in zip(ids, mask_bboxes(gt)):
            r0, c0, r1, c1 = _padded_box(box, rng.uniform(*config.pad_range, size=4), h, w)
            crops.append(_shrink(rgb[r0:r1, c0:c1], config.max_side))
            labels.append(int(labels_o[obj]))
            sources.append(SOURCES.index("gt"))

    if proposal_masks_rhw is not None and len(proposal_masks_rhw):
        props = np.asarray(proposal_masks_rhw, bool)
        if props.shape[1:] != (h, w):
            raise ValueError(f"proposal_masks_rhw: expected masks of the image's size {(h, w)}, got {props.shape[1:]}")
        area = props.reshape(len(props), -1).sum(axis=1)
        props, area = props[area >= config.min_area_px], area[area >= config.min_area_px]
        if len(props):
            boxes = mask_bboxes(props)
            on_obj = (props & (seg >= 0)[None]).reshape(len(props), -1).sum(axis=1) / area
            if len(ids):
                inter = np.einsum("rhw,ohw->ro", props.astype(np.float32), gt.astype(np.float32))
                union = area[:, None] + gt.reshape(len(gt), -1).sum(axis=1)[None] - inter
                iou = inter / np.maximum(union, 1)
                best = iou.argmax(axis=1)
                best_iou = iou.max(axis=1)
            else:
                best, best_iou = np.zeros(len(props), np.int64), np.zeros(len(props))
            for r in np.flatnonzero(best_iou >= config.match_iou):
                r0, c0, r1, c1 = boxes[r]
                crops.append(_shrink(rgb[r0:r1, c0:c1], config.max_side))
                labels.append(int(labels_o[ids[best[r]]]))
                sources.append(SOURCES.index("proposer"))
            if background_label is not None and config.max_background:
                bg = np.flatnonzero((best_iou < config.background_iou) & (on_obj <= config.background_object_fraction))
                for r in rng.permutation(bg)[: config.max_background]:
                    r0, c0, r1, c1 = boxes[r]
                    crops.append(_shrink(rgb[r0:r1, c0:c1], config.max_side))
                    labels.append(int(background_label))
                    sources.append(SOURCES.index("background"))

    if scene_label is not None:
        crops.append(_shrink(rgb, config.frame_side))
        labels.append(int(scene_label))
        sources.append(SOURCES.index("frame"))
    return crops, labels, sources


def build_crop_data(
    views: Iterable,
    classes: Sequence[ObjectClass],
    rng: np.random.Generator,
    *,
    proposer=None,
    config: CropConfig = CropConfig(),
    background_class: ObjectClass = BACKGROUND_CLASS,
    scene_class: ObjectClass = SCENE_CLASS,
) -> CropData:
    """Crops of many labelled views.

    Args:
        views: :class:`tower_training.views.TabletopView` (or objects with a ``frame``
            :class:`~conceptfusion.frames.RGBDFrame` with ``segmentation``, a ``scene_seed``
            and ``object_names``).
        classes: the label vocabulary; objects whose name is not a class get no crop. The
            background and scene crops are made only when ``background_class`` /
            ``scene_class`` are in it.
        rng: randomness of the crops.
        proposer: a mask proposer (``propose(rgb, depth, K)``), or ``None`` for
            ground-truth crops (and frames) only.
        background_class, scene_class: the labels of background masks and whole views
            (default: the table's, :data:`BACKGROUND_CLASS` and :data:`SCENE_CLASS`).
    """
    names = [c.name for c in classes]
    if len(set(names)) != len(names):
        raise ValueError("classes: expected distinct class names")
    index = {n: i for i, n in enumerate(names)}
    bg = index.get(background_class.name)
    sc = index.get(scene_class.name)
    images, labels, sources, seeds, view_ids = [], [], [], [], []
    for v, view in enumerate(views):
        obj_labels = [index.get(n, -1) for n in view.object_names]
        f = view.frame
        masks = proposer.propose(f.rgb, f.depth, f.K) if proposer is not None else None
        c, lab, src = crops_from_view(f.rgb, f.segmentation, obj_labels, rng, proposal_masks_rhw=masks,
                                      background_label=bg, scene_label=sc, config=config)
        images += c
        labels += lab
        sources += src
        seeds += [int(view.scene_seed)] * len(c)
        view_ids += [v] * len(c)
        if v % 100 == 0:
            logger.info("view %d: %d crops so far", v, len(images))
    return CropData(images, np.array(labels, np.int64), np.array(sources, np.int64), np.array(seeds, np.int64),
                    np.array(view_ids, np.int64), tuple(names))
