"""CLIP exported to ONNX, run by onnxruntime on the CPU: no torch at run time.

**Folder layout** (written by :func:`export_clip_to_onnx`, read by :class:`OnnxClipEncoder`)::

    DIR/
      image.onnx      input  pixel_values    float32 (n, 3, H, W)  (H, W: the crop size)
                      output image_embeds    float32 (n, d)        (any scale; rows are normalised here)
      text.onnx       inputs input_ids       int64   (n, L)        (L: any length up to max_length)
                             attention_mask  int64   (n, L)        (optional input; 1 = token, 0 = padding)
                      output text_embeds     float32 (n, d)
      tokenizer.json  a `tokenizers` tokenizer that adds the start and end tokens itself
      clip_onnx.json  {"format": "conceptfusion-clip-onnx", "version": 1, "embed_dim": d,
                       "max_length": L_max, "pad_token_id": int,
                       "preprocess": {ClipPreprocess fields}, "source": "where it came from"}

Images are preprocessed by :func:`conceptfusion.perception.clip_hf.clip_preprocess` with the settings in
``clip_onnx.json`` (the checkpoint's own). Texts are tokenised with ``tokenizer.json``,
truncated to ``max_length`` tokens and right-padded with ``pad_token_id`` to the longest text
of the batch.

Loading checks the graphs before anything runs: input names, ranks, dtypes and fixed sizes,
and that both graphs output ``embed_dim``-d vectors; a mismatch raises
:class:`~conceptfusion.errors.CheckpointError` saying what was expected. The exporter writes
each graph as one protobuf, which caps a tower at 2 GB (ViT-L/14 fits, ViT-H/14 does not).
"""

from __future__ import annotations

import io
import json
import logging
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import Sequence

import numpy as np

from conceptfusion.perception.clip_hf import ClipPreprocess, clip_preprocess
from conceptfusion.perception.encoders import check_texts, embed_in_batches, onnx_session_options, unit_rows
from conceptfusion.errors import CheckpointError, MissingDependencyError

__all__ = ["OnnxClipEncoder", "export_clip_to_onnx", "check_onnx_folder", "MANIFEST_NAME", "LAYOUT_FILES"]

logger = logging.getLogger(__name__)

_EXTRA = 'pip install "conceptfusion-harness[perception]"'
_FORMAT = "conceptfusion-clip-onnx"
_VERSION = 1
MANIFEST_NAME = "clip_onnx.json"
"""Name of the JSON manifest in an ONNX CLIP folder."""
LAYOUT_FILES = ("image.onnx", "text.onnx", "tokenizer.json", MANIFEST_NAME)
"""Every file an ONNX CLIP folder must hold."""


def check_onnx_folder(folder: str | Path) -> Path:
    """``folder`` as a path, once it holds every file of :data:`LAYOUT_FILES` (reads none of them).

    Raises:
        FileNotFoundError: no folder there, or a file missing (naming them).
    """
    d = Path(folder).expanduser()
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: no such folder; expected an ONNX CLIP folder with {', '.join(LAYOUT_FILES)}")
    missing = [f for f in LAYOUT_FILES if not (d / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{d}: expected {', '.join(LAYOUT_FILES)} in an ONNX CLIP folder, missing {', '.join(missing)}")
    return d


def _read_manifest(path: Path) -> dict:
    try:
        info = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise CheckpointError(f"{path}: expected the JSON manifest of an ONNX CLIP folder, could not read it: {exc}") from exc
    if not isinstance(info, dict) or info.get("format") != _FORMAT:
        raise CheckpointError(f"{path}: expected a manifest with format {_FORMAT!r}, got {str(info)[:80]}")
    if int(info.get("version", 0)) > _VERSION:
        raise CheckpointError(f"{path}: written by format version {info.get('version')}, this code reads up to {_VERSION}")
    try:
        pre = dict(info["preprocess"])
        pre["crop_hw"] = tuple(pre["crop_hw"])
        pre["resize_hw"] = tuple(pre["resize_hw"]) if pre.get("resize_hw") else None
        pre["mean"], pre["std"] = tuple(pre["mean"]), tuple(pre["std"])
        info["preprocess"] = ClipPreprocess(**pre)
        info["embed_dim"] = int(info["embed_dim"])
        info["max_length"] = int(info["max_length"])
        info["pad_token_id"] = int(info["pad_token_id"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: manifest field missing or malformed: {exc!r}") from exc
    return info


def _session(path: Path, threads: int | None):
    import onnxruntime as ort

    opts = onnx_session_options(threads)
    try:
        return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own exception types
        raise CheckpointError(f"{path}: expected a loadable ONNX graph, onnxruntime could not load it: {exc}") from exc


def _output_dim(session, path: Path) -> int:
    outs = session.get_outputs()
    shape = outs[0].shape if outs else None
    if not outs or len(shape) != 2 or not isinstance(shape[1], int):
        raise CheckpointError(f"{path}: expected an (n, d) embedding output with a fixed d, got {shape}")
    return int(shape[1])


class OnnxClipEncoder:
    """An exported CLIP (see the module docstring) behind the :class:`~conceptfusion.perception.encoders.Encoder` protocol.

    Args:
        folder: the ONNX CLIP folder.
        batch_size: images or strings per onnxruntime call.
        threads: onnxruntime intra-op threads (``None``: ``$CF_THREADS``, else 2).

    Raises:
        FileNotFoundError: the folder or one of :data:`LAYOUT_FILES` is missing.
        CheckpointError: a file is corrupt, or the graphs do not match the layout.
        MissingDependencyError: the ``tokenizers`` package is not installed.
    """

    def __init__(self, folder: str | Path, *, batch_size: int = 32, threads: int | None = None) -> None:
        if not isinstance(batch_size, int) or batch_size < 1:
            raise ValueError(f"batch_size: expected an int >= 1, got {batch_size!r}")
        d = check_onnx_folder(folder)
        try:
            from tokenizers import Tokenizer
        except ImportError as exc:
            raise MissingDependencyError(f"ONNX CLIP needs the tokenizers package: {_EXTRA}") from exc
        info = _read_manifest(d / MANIFEST_NAME)
        try:
            self._tokenizer = Tokenizer.from_file(str(d / "tokenizer.json"))
        except Exception as exc:
            raise CheckpointError(f"{d / 'tokenizer.json'}: expected a `tokenizers` tokenizer file, could not load it: {exc}") from exc
        self._tokenizer.no_padding()
        self._tokenizer.enable_truncation(info["max_length"])
        self.folder = d
        self.info = info
        self.preprocess: ClipPreprocess = info["preprocess"]
        self._dim = info["embed_dim"]
        self._pad = info["pad_token_id"]
        self._batch = batch_size
        self._image = _session(d / "image.onnx", threads)
        self._text = _session(d / "text.onnx", threads)
        self._check_graphs()

    def _check_graphs(self) -> None:
        d = self.folder
        img_in = self._image.get_inputs()
        ch, cw = self.preprocess.crop_hw
        if len(img_in) != 1 or img_in[0].name != "pixel_values" or img_in[0].type != "tensor(float)":
            got = [(i.name, i.type) for i in img_in]
            raise CheckpointError(f"{d / 'image.onnx'}: expected one float32 input 'pixel_values', got {got}")
        shape = img_in[0].shape
        if len(shape) != 4 or any(isinstance(s, int) and s != e for s, e in zip(shape[1:], (3, ch, cw))):
            raise CheckpointError(f"{d / 'image.onnx'}: expected input shape (n, 3, {ch}, {cw}), got {shape}")
        txt_in = {i.name: i for i in self._text.get_inputs()}
        if "input_ids" not in txt_in or not set(txt_in) <= {"input_ids", "attention_mask"}:
            raise CheckpointError(f"{d / 'text.onnx'}: expected inputs 'input_ids' and optionally 'attention_mask', got {sorted(txt_in)}")
        for name, i in txt_in.items():
            if i.type != "tensor(int64)" or len(i.shape) != 2:
                raise CheckpointError(f"{d / 'text.onnx'}: expected {name} as (n, L) int64, got {i.shape} {i.type}")
        self._text_inputs = tuple(txt_in)
        img_dim = _output_dim(self._image, d / "image.onnx")
        txt_dim = _output_dim(self._text, d / "text.onnx")
        if img_dim != self._dim or txt_dim != self._dim:
            raise CheckpointError(
                f"{d}: expected both graphs to output {self._dim}-d embeddings ({MANIFEST_NAME} embed_dim), "
                f"got image.onnx {img_dim}-d and text.onnx {txt_dim}-d"
            )

    @property
    def dim(self) -> int:
        return self._dim

    def tokenize(self, texts: Sequence[str]) -> dict[str, np.ndarray]:
        """Token ids and attention mask, right-padded to the longest text.

        Shape:
            n strings -> ``input_ids`` and ``attention_mask``, each (n, L) int64.
        """
        encs = self._tokenizer.encode_batch(check_texts(texts))
        length = max(len(e.ids) for e in encs)
        ids = np.full((len(encs), length), self._pad, np.int64)
        mask = np.zeros((len(encs), length), np.int64)
        for i, e in enumerate(encs):
            ids[i, : len(e.ids)] = e.ids
            mask[i, : len(e.ids)] = 1
        return {"input_ids": ids, "attention_mask": mask}

    def encode_image(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Embed RGB images.

        Shape:
            n images (h_i, w_i, 3) uint8 -> (n, d) float32, unit rows.
        """
        x = clip_preprocess(images, self.preprocess)
        return embed_in_batches(x, self._batch, self._dim,
                                lambda batch: unit_rows(self._image.run(None, {"pixel_values": batch})[0]))

    def encode_text(self, texts: Sequence[str]) -> np.ndarray:
        """Embed non-empty strings.

        Shape:
            n strings -> (n, d) float32, unit rows.
        """
        return embed_in_batches(check_texts(texts), self._batch, self._dim, self._embed_text_batch)

    def _embed_text_batch(self, texts: list[str]) -> np.ndarray:
        feeds = self.tokenize(texts)
        return unit_rows(self._text.run(None, {k: feeds[k] for k in self._text_inputs})[0])


def export_clip_to_onnx(hf_model_dir: str | Path, out_dir: str | Path, *, opset: int = 17, verify: bool = True) -> Path:
    """Export a local Hugging Face CLIP checkpoint to the ONNX folder layout (module docstring).

    Args:
        hf_model_dir: a checkpoint folder :class:`~conceptfusion.perception.clip_hf.HFClipEncoder` loads.
        out_dir: folder to write (created; existing layout files are replaced).
        opset: ONNX opset version.
        verify: run both graphs once with onnxruntime and compare with torch (max abs
            difference 1e-3 on normalised embeddings), raising ``RuntimeError`` otherwise.

    Returns:
        ``out_dir`` as a ``Path``.
    """
    from conceptfusion.perception.clip_hf import HFClipEncoder
    from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text

    try:
        import torch
    except ImportError as exc:
        raise MissingDependencyError(f"exporting CLIP to ONNX needs torch and transformers: {_EXTRA}") from exc
    hf = HFClipEncoder(hf_model_dir)
    backend = getattr(hf.tokenizer, "backend_tokenizer", None)
    if backend is None:
        raise CheckpointError(f"{hf_model_dir}: expected a fast (tokenizers-backed) tokenizer to write tokenizer.json")
    model = hf.model
    if hasattr(model, "set_attn_implementation"):
        model.set_attn_implementation("eager")  # plain matmul attention exports to any opset

    def features(out):
        return out if isinstance(out, torch.Tensor) else out.pooler_output

    class ImageTower(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.model = model

        def forward(self, pixel_values):
            return features(self.model.get_image_features(pixel_values=pixel_values))

    class TextTower(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.model = model

        def forward(self, input_ids, attention_mask):
            return features(self.model.get_text_features(input_ids=input_ids, attention_mask=attention_mask))

    ch, cw = hf.preprocess.crop_hw
    pixels = torch.from_numpy(np.random.default_rng(0).standard_normal((2, 3, ch, cw)).astype(np.float32))
    tokens = {k: torch.from_numpy(v) for k, v in hf.tokenize(["a photo of a thing", "a"]).items()}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    graphs = {}
    for name, module, args, in_names, out_name, axes in (
        ("image.onnx", ImageTower(), (pixels,), ["pixel_values"], "image_embeds", {"pixel_values": {0: "n"}}),
        (
            "text.onnx",
            TextTower(),
            (tokens["input_ids"], tokens["attention_mask"]),
            ["input_ids", "attention_mask"],
            "text_embeds",
            {"input_ids": {0: "n", 1: "L"}, "attention_mask": {0: "n", 1: "L"}},
        ),
    ):
        buf = io.BytesIO()
        with warnings.catch_warnings():  # the TorchScript exporter warns about deprecation and tracing
            warnings.simplefilter("ignore")
            torch.onnx.export(
                module.eval(), args, buf, input_names=in_names, output_names=[out_name],
                dynamic_axes={**axes, out_name: {0: "n"}}, opset_version=opset, dynamo=False,
            )
        graphs[name] = buf.getvalue()
    for name, data in graphs.items():
        atomic_write_bytes(out / name, data)
    atomic_write_text(out / "tokenizer.json", backend.to_str())
    pad = hf.tokenizer.pad_token_id if hf.tokenizer.pad_token_id is not None else hf.tokenizer.eos_token_id
    manifest = {
        "format": _FORMAT,
        "version": _VERSION,
        "embed_dim": hf.dim,
        "max_length": hf.max_length,
        "pad_token_id": int(pad),
        "preprocess": asdict(hf.preprocess),
        "source": str(Path(hf_model_dir).expanduser().resolve()),
    }
    atomic_write_text(out / MANIFEST_NAME, json.dumps(manifest, indent=2, sort_keys=True))
    if verify:
        onnx_enc = OnnxClipEncoder(out)
        texts = ["a photo of a thing", "a"]
        rng = np.random.default_rng(1)
        images = [rng.integers(0, 256, (ch + 5, cw + 9, 3), dtype=np.uint8)]
        for what, a, b in (
            ("text", hf.encode_text(texts), onnx_enc.encode_text(texts)),
            ("image", hf.encode_image(images), onnx_enc.encode_image(images)),
        ):
            err = float(np.abs(a - b).max())
            if err > 1e-3:
                raise RuntimeError(f"ONNX export of the {what} tower disagrees with torch: max abs difference {err:.2e}")
    logger.info("exported %s to %s", hf_model_dir, out)
    return out
