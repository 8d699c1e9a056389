"""LiT-style training of the embedded image tower against a frozen text tower.

Each class (an object instance, or a category) has several phrases: its name and a few
descriptions ("a bottle of wine", "something to drink"). Their text embeddings, averaged
and re-normalised, are the class's fixed target. The image tower learns to put every crop
of the class next to that target with a softmax cross-entropy over all training classes
(a contrastive loss whose "text side" is frozen), with a learned logit scale as in CLIP.

Augmentations model what the mask proposer hands the tower: loose or tight boxes (random
resized crops), partial occlusion (cut-out patches), brightness/contrast changes and
mirror images. Hue is never changed: colour words are part of the text.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from conceptfusion.perception.image_tower import TowerConfig, build_tower, preprocess

__all__ = [
    "CropSet", "TrainConfig", "class_targets", "train_tower", "retrieval_accuracy", "augment", "shrink", "half_res",
    "multicaption_loss",
    "train_tower_multicaption", "make_optimiser", "descend", "name_top1", "torch_embed_fn",
    "load_tower_weights_from_onnx", "export_checked",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class CropSet:
    """Crops with class labels.

    Shape:
        ``images``: n arrays (h_i, w_i, 3) uint8; ``labels`` (n,) int64 indices into the
        class list they are used with.
    """

    images: list
    labels: np.ndarray

    def __post_init__(self) -> None:
        if len(self.images) != len(self.labels):
            raise ValueError(f"CropSet: {len(self.images)} images but {len(self.labels)} labels")

    def subset(self, mask: np.ndarray) -> "CropSet":
        idx = np.flatnonzero(mask)
        return CropSet([self.images[i] for i in idx], np.asarray(self.labels)[idx])


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings of :func:`train_tower`."""

    steps: int = 1500
    """Optimiser steps."""
    batch_size: int = 128
    """Crops per step."""
    lr: float = 2e-3
    """Peak AdamW learning rate (cosine decay after a 5% warm-up)."""
    weight_decay: float = 0.05
    """AdamW weight decay."""
    seed: int = 0
    """Seeds torch and the augmentation generator."""
    tower: TowerConfig = field(default_factory=TowerConfig)
    """Architecture."""
    low_res_p: float = 0.0
    """Probability that a training crop is first shrunk by a factor drawn from ``low_res_scale``
    (area interpolation), as an object looks in a 160x120 frame or from a far camera; 0 draws
    nothing from the generator (the v1 recipe)."""
    low_res_scale: tuple[float, float] = (1.0, 4.0)
    """Range of that shrink factor."""


def class_targets(text_encoder, class_phrases: Sequence[Sequence[str]]) -> np.ndarray:
    """Mean of each class's phrase embeddings, re-normalised.

    Shape:
        C lists of phrases -> (C, d) float32 unit rows.
    """
    flat = [p for phrases in class_phrases for p in phrases]
    if not flat or any(len(p) == 0 for p in class_phrases):
        raise ValueError("class_phrases: expected at least one phrase per class")
    emb = np.asarray(text_encoder.encode_text(flat), np.float64)
    out, i = [], 0
    for phrases in class_phrases:
        v = emb[i : i + len(phrases)].mean(axis=0)
        out.append(v / max(np.linalg.norm(v), 1e-12))
        i += len(phrases)
    return np.asarray(out, np.float32)


def shrink(image: np.ndarray, factor: float) -> np.ndarray:
    """``image`` shrunk by ``factor`` >= 1 on both sides (area interpolation, at least 2x2).

    Shape:
        (h, w, 3) uint8 -> (max(2, h / factor), max(2, w / factor), 3) uint8.
    """
    import cv2

    h, w = image.shape[:2]
    size = (max(2, int(round(w / factor))), max(2, int(round(h / factor))))
    return image if size == (w, h) else cv2.resize(np.ascontiguousarray(image), size, interpolation=cv2.INTER_AREA)


def half_res(images) -> list[np.ndarray]:
    """Each crop shrunk by 2 on both sides (area interpolation): how it looks when the frame is
    rendered at half the size (160x120 instead of 320x240), as the agents' and map suites' are."""
    return [shrink(im, 2.0) for im in images]


def augment(image: np.ndarray, rng: np.random.Generator, *, low_res_p: float = 0.0,
            low_res_scale: tuple[float, float] = (1.0, 4.0)) -> np.ndarray:
    """One random view of a crop (see the module docstring); with probability ``low_res_p``
    the crop is first shrunk by a factor drawn from ``low_res_scale`` (:func:`shrink`).

    Shape:
        (h, w, 3) uint8 -> (h', w', 3) uint8.
    """
    if low_res_p > 0 and rng.random() < low_res_p:
        image = shrink(image, rng.uniform(*low_res_scale))
    h, w = image.shape[:2]
    scale = rng.uniform(0.65, 1.0)
    ch, cw = max(2, int(round(h * math.sqrt(scale) * rng.uniform(0.85, 1.15)))), max(2, int(round(w * math.sqrt(scale))))
    ch, cw = min(ch, h), min(cw, w)
    r0 = int(rng.integers(0, h - ch + 1))
    c0 = int(rng.integers(0, w - cw + 1))
    out = image[r0 : r0 + ch, c0 : c0 + cw].astype(np.float32)
    if rng.random() < 0.5:
        out = out[:, ::-1]
    gain = rng.uniform(0.7, 1.3)
    bias = rng.uniform(-20, 20)
    mean = out.mean()
    contrast = rng.uniform(0.8, 1.2)
    out = (out - mean) * contrast + mean
    out = out * gain + bias
    if rng.random() < 0.4:  # partial occlusion
        oh, ow = int(ch * rng.uniform(0.2, 0.45)), int(cw * rng.uniform(0.2, 0.45))
        if oh > 0 and ow > 0:
            y, x = int(rng.integers(0, ch - oh + 1)), int(rng.integers(0, cw - ow + 1))
            out[y : y + oh, x : x + ow] = rng.uniform(0, 255, 3)
    return np.clip(out, 0, 255).astype(np.uint8)



def make_optimiser(model, config, device=None):
    """The learnable logit scale (log 10 at start, on ``device``), AdamW over the tower and the
    scale, and the learning rate per step: linear warm-up over the first 5% of steps, then cosine
    decay to 0. The temperature is not decayed: decay would pull the logit scale towards 1."""
    import torch

    logit_scale = torch.nn.Parameter(torch.tensor(math.log(10.0), device=device))
    opt = torch.optim.AdamW([{"params": list(model.parameters())}, {"params": [logit_scale], "weight_decay": 0.0}],
                            lr=config.lr, weight_decay=config.weight_decay)
    warm = max(1, config.steps // 20)

    def lr_at(step: int) -> float:
        if step < warm:
            return config.lr * (step + 1) / warm
        t = (step - warm) / max(1, config.steps - warm)
        return config.lr * 0.5 * (1 + math.cos(math.pi * t))

    return logit_scale, opt, lr_at


def _batch(train: CropSet, labels: np.ndarray, rng: np.random.Generator, config):
    """A training batch: ``batch_size`` crops drawn with replacement, augmented, preprocessed;
    returns the image tensor and the class labels."""
    import torch

    idx = rng.integers(0, len(labels), config.batch_size)
    x = torch.from_numpy(preprocess([augment(train.images[i], rng, low_res_p=config.low_res_p, low_res_scale=config.low_res_scale)
                                     for i in idx], config.tower.input_size))
    return x, torch.from_numpy(labels[idx])


def descend(opt, loss, lr: float) -> None:
    """One optimiser step on ``loss`` at learning rate ``lr``."""
    for g in opt.param_groups:
        g["lr"] = lr
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()

def train_tower(train: CropSet, targets_cd: np.ndarray, config: TrainConfig = TrainConfig(), *, log_every: int = 100):
    """Train a tower so crops land on their class targets; returns the torch module (eval mode).

    Shape:
        ``targets_cd`` (C, d) unit rows, C > max(train.labels), d = config.tower.embed_dim.
    """
    import torch

    if targets_cd.shape[1] != config.tower.embed_dim:
        raise ValueError(
            f"targets_cd: expected dimension {config.tower.embed_dim} (the tower's embed_dim), got {targets_cd.shape[1]}"
        )
    if len(train.labels) == 0:
        raise ValueError("train: expected at least one crop")
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    model = build_tower(config.tower)
    logit_scale, opt, lr_at = make_optimiser(model, config)

    targets = torch.from_numpy(np.ascontiguousarray(targets_cd, np.float32))
    labels = np.asarray(train.labels, np.int64)
    model.train()
    for step in range(config.steps):
        x, y = _batch(train, labels, rng, config)
        emb = model(x)
        logits = logit_scale.exp().clamp(max=100.0) * emb @ targets.T
        loss = torch.nn.functional.cross_entropy(logits, y)
        descend(opt, loss, lr_at(step))
        if log_every and (step % log_every == 0 or step == config.steps - 1):
            acc = float((logits.argmax(1) == y).float().mean())
            logger.info("step %d/%d loss %.3f batch acc %.2f scale %.1f", step, config.steps, loss.item(), acc, logit_scale.exp().item())
    return model.eval()


def retrieval_accuracy(embed_fn, crops: CropSet, targets_cd: np.ndarray, *, candidates: np.ndarray | None = None) -> float:
    """Top-1 crop-to-text retrieval accuracy.

    ``embed_fn(images) -> (n, d)``; each crop is matched against the rows of ``targets_cd``
    (optionally only the class indices in ``candidates``).
    """
    if len(crops.labels) == 0:
        return float("nan")
    emb = np.asarray(embed_fn(crops.images), np.float32)
    cand = np.arange(len(targets_cd)) if candidates is None else np.asarray(candidates)
    pred = cand[np.argmax(emb @ targets_cd[cand].T, axis=1)]
    return float(np.mean(pred == np.asarray(crops.labels)))


def multicaption_loss(logits_bt, positives_bt, weights_t=None):
    """Contrastive loss of crops against a bank of captions with several positives per crop.

    For each crop and each of its positive captions p: ``-log softmax`` of p among p and the
    crop's *negatives* (the other positives are masked out, so "mug" and "cup" of the same crop
    do not compete), averaged over the crop's positives with ``weights_t`` (default: uniform),
    then over crops.

    Shape:
        logits (B, T) torch float, positives (B, T) torch bool (at least one per row),
        weights (T,) -> scalar.
    """
    import torch

    neg_inf = torch.finfo(logits_bt.dtype).min
    neg = logits_bt.masked_fill(positives_bt, neg_inf)  # (B, T): negatives only
    neg_lse = torch.logsumexp(neg, dim=1, keepdim=True)  # (B, 1)
    # log softmax of each positive among itself and the negatives
    per = logits_bt - torch.logaddexp(logits_bt, neg_lse.expand_as(logits_bt))  # (B, T)
    w = positives_bt.to(logits_bt.dtype)
    if weights_t is not None:
        w = w * weights_t[None, :]
    return -((per * w).sum(dim=1) / w.sum(dim=1).clamp(min=1e-12)).mean()


def train_tower_multicaption(
    train: CropSet,
    captions_td: np.ndarray,
    positives_ct: np.ndarray,
    config: TrainConfig = TrainConfig(),
    *,
    caption_weights_t: np.ndarray | None = None,
    select_fn=None,
    select_every: int = 200,
    log_every: int = 100,
    init_onnx: str | None = None,
):
    """Train a tower so each crop matches every caption of its class (multi-positive loss).

    Args:
        train: crops labelled with class indices (rows of ``positives_ct``).
        captions_td: text embeddings of the caption bank, unit rows.
        positives_ct: class c has caption t.
        caption_weights_t: weight of each caption as a positive (default uniform).
        select_fn: ``select_fn(embed_fn) -> float`` (higher is better), evaluated every
            ``select_every`` steps and at the end on the VALIDATION set; the weights with the
            best value are returned. ``None``: the last weights.
        init_onnx: start from an exported tower's weights (:func:`load_tower_weights_from_onnx`)
            instead of a random initialisation; its batch norms then stay frozen (eval mode).

    Returns:
        ``(model in eval mode, history)``; history lists ``{"step", "val"}`` of every selection
        evaluation and ``"best_step"``.

    Shape:
        captions (T, d), positives (C, T) bool, weights (T,).
    """
    import copy

    import torch

    if captions_td.shape[1] != config.tower.embed_dim:
        raise ValueError(f"captions_td: expected dimension {config.tower.embed_dim}, got {captions_td.shape[1]}")
    if positives_ct.shape[1] != len(captions_td) or not positives_ct.any(axis=1).all():
        raise ValueError("positives_ct: expected (C, T) with at least one caption per class")
    if len(train.labels) == 0:
        raise ValueError("train: expected at least one crop")
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    model = build_tower(config.tower)
    if init_onnx is not None:
        load_tower_weights_from_onnx(model, init_onnx)
    logit_scale, opt, lr_at = make_optimiser(model, config)

    def set_train() -> None:
        model.train()
        if init_onnx is not None:  # folded batch norms stay the identity
            for m in model.modules():
                if isinstance(m, torch.nn.BatchNorm2d):
                    m.eval()

    caps = torch.from_numpy(np.ascontiguousarray(captions_td, np.float32))
    pos = torch.from_numpy(np.asarray(positives_ct, bool))
    wts = None if caption_weights_t is None else torch.from_numpy(np.asarray(caption_weights_t, np.float32))
    labels = np.asarray(train.labels, np.int64)
    history: dict = {"evals": [], "best_step": None}
    best_val, best_state = -math.inf, None

    def embed(images):
        out = []
        model.eval()
        with torch.no_grad():
            for s in range(0, len(images), 256):
                out.append(model(torch.from_numpy(preprocess(images[s : s + 256], config.tower.input_size))).numpy())
        set_train()
        return np.concatenate(out) if out else np.zeros((0, config.tower.embed_dim), np.float32)

    set_train()
    for step in range(config.steps):
        x, y = _batch(train, labels, rng, config)
        emb = model(x)
        logits = logit_scale.exp().clamp(max=100.0) * emb @ caps.T
        loss = multicaption_loss(logits, pos[y], wts)
        descend(opt, loss, lr_at(step))
        if log_every and (step % log_every == 0 or step == config.steps - 1):
            hit = pos[y, logits.argmax(1)].float().mean()
            logger.info("step %d/%d loss %.3f batch top-1 caption is a positive %.2f scale %.1f",
                        step, config.steps, loss.item(), float(hit), logit_scale.exp().item())
        last = step == config.steps - 1
        if select_fn is not None and ((step + 1) % select_every == 0 or last):
            v = float(select_fn(embed))
            history["evals"].append({"step": step + 1, "val": v})
            logger.info("step %d: validation %.4f", step + 1, v)
            if v > best_val:
                best_val, history["best_step"] = v, step + 1
                best_state = copy.deepcopy(model.state_dict())
    if best_state is not None:
        model.load_state_dict(best_state)
    history["best_val"] = None if best_state is None else best_val
    history["logit_scale"] = float(logit_scale.exp().item())
    return model.eval(), history


def name_top1(embed_fn, image_sets: Sequence[Sequence[np.ndarray]], truth_n: np.ndarray, names_td: np.ndarray) -> float:
    """The model-selection score: top-1 of each crop's true name among ``names_td``, the mean
    over ``image_sets`` (the same crops at several resolutions); NaN for no crops.

    Shape:
        each set n crops (h_i, w_i, 3) uint8, ``truth_n`` (n,) row indices of ``names_td`` (T, d).
    """
    if not len(truth_n):
        return float("nan")
    hits = [np.mean(np.argmax(np.asarray(embed_fn(ims), np.float32) @ names_td.T, axis=1) == truth_n) for ims in image_sets]
    return float(np.mean(hits))


def torch_embed_fn(model, input_size: int):
    """``embed(images) -> (n, d)`` float32 with a torch tower (no gradients, batches of 256).

    Shape:
        n crops (h_i, w_i, 3) uint8 -> (n, d).
    """
    import torch

    def embed(images) -> np.ndarray:
        out = []
        with torch.no_grad():
            for s in range(0, len(images), 256):
                out.append(model(torch.from_numpy(preprocess(images[s : s + 256], input_size))).numpy())
        return np.concatenate(out) if out else np.zeros((0, model.head.out_features), np.float32)

    return embed


def load_tower_weights_from_onnx(model, onnx_path) -> None:
    """Put an exported tower's weights (``tower.onnx``) into a torch tower of the same config.

    The exporter folds every batch norm into the convolution before it, so each convolution
    takes the folded weight and bias and its batch norm becomes the identity (weight 1, bias
    the folded bias, running mean 0, running variance ``1 - eps``). The module then computes
    what the ONNX graph computes, with batch norms in eval mode; train it with
    ``freeze_batchnorm=True`` (:func:`train_tower_multicaption`) to keep it so.
    """
    import onnx
    import torch
    from onnx import numpy_helper

    g = onnx.load(str(onnx_path)).graph
    inits = {i.name: numpy_helper.to_array(i) for i in g.initializer}
    order = {name: k for k, name in enumerate(inits)}  # the exporter lists folded weights in module order
    convs = sorted((n for n in g.node if n.op_type == "Conv"), key=lambda n: order[n.input[1]])
    mods = list(model.modules())
    pairs = []  # (conv, the batch norm after it)
    for i, m in enumerate(mods):
        if isinstance(m, torch.nn.Conv2d):
            bn = next(x for x in mods[i + 1:] if isinstance(x, torch.nn.BatchNorm2d))
            pairs.append((m, bn))
    if len(pairs) != len(convs):
        raise ValueError(f"{onnx_path}: {len(convs)} convolutions, but the tower has {len(pairs)}")
    with torch.no_grad():
        for (conv, bn), node in zip(pairs, convs):
            w, b = inits[node.input[1]], inits[node.input[2]]
            if tuple(w.shape) != tuple(conv.weight.shape):
                raise ValueError(f"{onnx_path}: convolution {node.name} has shape {w.shape}, the tower {tuple(conv.weight.shape)}")
            conv.weight.copy_(torch.from_numpy(np.array(w)))
            bn.weight.fill_(1.0)
            bn.bias.copy_(torch.from_numpy(np.array(b)))
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
        model.head.weight.copy_(torch.from_numpy(np.array(inits["head.weight"])))
        model.head.bias.copy_(torch.from_numpy(np.array(inits["head.bias"])))


def export_checked(model, tower_cfg, out_dir, metadata: dict, text_encoder, sample_images) -> int:
    """Export ``model`` to ONNX in ``out_dir`` with ``metadata`` (``tower.json``), reload it with
    onnxruntime and compare its embeddings of ``sample_images`` with torch's; prints the largest
    difference and returns the exit status of a training command (1 when they disagree by more
    than 1e-3)."""
    import sys

    from conceptfusion.perception.image_tower import EmbeddedEncoder, export_tower_onnx

    export_tower_onnx(model, tower_cfg, out_dir, metadata=metadata)
    enc = EmbeddedEncoder(out_dir, text_encoder)
    gap = float(np.max(np.abs(enc.encode_image(sample_images) - torch_embed_fn(model, tower_cfg.input_size)(sample_images))))
    print(f"exported to {out_dir} (onnxruntime vs torch max difference {gap:.1e})")
    if gap > 1e-3:
        print("onnxruntime and torch disagree", file=sys.stderr)
        return 1
    return 0
