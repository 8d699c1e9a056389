"""Audio queries: the optional ``encode_audio`` capability, and audio-language encoders in ONNX.

An encoder that can embed sounds into the map's concept space implements
:class:`AudioEncoder` next to (or instead of) :class:`~conceptfusion.perception.encoders.Encoder`. No
audio-language model ships offline, so :class:`OnnxAudioEncoder` runs one the user exports
(for example the audio tower of a CLAP or AudioCLIP model, aligned to the image/text encoder
the map was built with); :func:`export_audio_onnx` writes a torch module in that layout.

**Folder layout**::

    DIR/
      audio.onnx   input  waveform  float32 (n, T): mono samples in [-1, 1] at sample_rate;
                                    T fixed (clip_samples) or dynamic
                   output float32 (n, d)  (any scale; rows are normalised here)
      audio.json   {"format": "conceptfusion-audio-onnx", "version": 1, "sample_rate": Hz,
                    "embed_dim": d, "clip_samples": T or null, "aligned_to": "free text"}

With a fixed ``clip_samples``, shorter clips are zero-padded at the end and longer ones
centre-trimmed; with ``null`` each distinct clip length runs as its own batch. Audio at
another sample rate is refused (resample it first), so a 44.1 kHz clip never silently plays
at the wrong speed. Spoken-word queries without such a model: :mod:`conceptfusion.perception.speech`.
"""

from __future__ import annotations

import io
import json
import logging
import numbers
import warnings
from pathlib import Path
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from conceptfusion.errors import CheckpointError, DtypeError, MissingDependencyError, ShapeError
from conceptfusion.perception.encoders import onnx_session_options, unit_rows

__all__ = ["AudioEncoder", "check_waveforms", "OnnxAudioEncoder", "export_audio_onnx", "AUDIO_MANIFEST"]

logger = logging.getLogger(__name__)

_FORMAT = "conceptfusion-audio-onnx"
_VERSION = 1
AUDIO_MANIFEST = "audio.json"
"""Name of the JSON manifest in an ONNX audio-encoder folder."""


@runtime_checkable
class AudioEncoder(Protocol):
    """Sounds to unit vectors of the map's concept space (an optional encoder capability)."""

    @property
    def dim(self) -> int:
        """Embedding dimension ``d``."""
        ...

    sample_rate: int
    """The one sample rate (Hz) the encoder accepts."""

    def encode_audio(self, waveforms: Sequence[np.ndarray], sample_rate: int) -> np.ndarray:
        """Embed mono clips recorded at ``sample_rate``. Returns (n, d) float32, unit rows."""
        ...


def check_waveforms(waveforms: Sequence[np.ndarray], sample_rate: int, expected_rate: int) -> list[np.ndarray]:
    """Validate a batch of mono clips and convert them to float32 in [-1, 1].

    Accepts float arrays (taken as already in [-1, 1]) and int16 PCM (divided by 32768).

    Shape:
        n clips (n_samples_i,) -> n float32 arrays (n_samples_i,).

    Raises:
        ValueError: wrong sample rate, empty or non-finite clips, an empty batch.
        ShapeError: a clip that is not 1-D.
        DtypeError: a clip that is not float or int16.
    """
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, numbers.Integral):
        raise TypeError(f"sample_rate: expected an int in Hz, got {type(sample_rate).__name__}")
    if int(sample_rate) != int(expected_rate):
        raise ValueError(f"sample_rate: expected audio at {expected_rate} Hz, got {sample_rate} Hz (resample it first)")
    if isinstance(waveforms, np.ndarray) and waveforms.ndim == 1:
        raise ShapeError(
            "waveforms: expected a sequence of (n_samples,) clips or an (n, n_samples) array, got one (n_samples,) clip"
        )
    out = []
    for i, w in enumerate(waveforms):
        if not isinstance(w, np.ndarray):
            raise DtypeError(f"waveforms[{i}]: expected a numpy array, got {type(w).__name__}")
        if w.ndim != 1 or w.size == 0:
            raise ShapeError(f"waveforms[{i}]: expected a non-empty mono (n_samples,) array, got shape {w.shape}")
        if w.dtype == np.int16:
            w = w.astype(np.float32) / 32768.0
        elif w.dtype.kind == "f":
            w = w.astype(np.float32)
            if not np.all(np.isfinite(w)):
                raise ValueError(f"waveforms[{i}]: expected finite samples, found NaN or inf")
        else:
            raise DtypeError(f"waveforms[{i}]: expected float samples in [-1, 1] or int16 PCM, got {w.dtype}")
        out.append(w)
    if not out:
        raise ValueError("waveforms: expected at least one clip, got none")
    return out


def _fit(w: np.ndarray, length: int) -> np.ndarray:
    """Zero-pad at the end or centre-trim to ``length`` samples."""
    if len(w) >= length:
        start = (len(w) - length) // 2
        return w[start : start + length]
    return np.concatenate([w, np.zeros(length - len(w), np.float32)])


class OnnxAudioEncoder:
    """An audio-language encoder exported to ONNX (see the module docstring): an :class:`AudioEncoder`.

    Args:
        folder: the folder with ``audio.onnx`` and ``audio.json``.
        expected_dim: if given, the dimension of the encoder whose space the audio must
            share (checked at load time).
        threads: onnxruntime intra-op threads (``None``: ``$CF_THREADS``, else 2).

    Raises:
        FileNotFoundError: the folder or one of its files is missing.
        CheckpointError: corrupt files, a graph that does not match the manifest, or an
            output size other than ``expected_dim``.
    """

    def __init__(self, folder: str | Path, *, expected_dim: int | None = None, threads: int | None = None) -> None:
        import onnxruntime as ort

        d = Path(folder).expanduser()
        if not d.is_dir():
            raise FileNotFoundError(f"{d}: no such folder; expected an audio encoder folder with audio.onnx and {AUDIO_MANIFEST}")
        for name in ("audio.onnx", AUDIO_MANIFEST):
            if not (d / name).is_file():
                raise FileNotFoundError(f"{d}: expected audio.onnx and {AUDIO_MANIFEST}, missing {name}")
        info = self._read_manifest(d / AUDIO_MANIFEST)
        opts = onnx_session_options(threads)
        try:
            self._session = ort.InferenceSession(str(d / "audio.onnx"), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types
            raise CheckpointError(f"{d / 'audio.onnx'}: expected a loadable ONNX graph, onnxruntime could not load it: {exc}") from exc
        ins, outs = self._session.get_inputs(), self._session.get_outputs()
        if len(ins) != 1 or ins[0].name != "waveform" or ins[0].type != "tensor(float)" or len(ins[0].shape) != 2:
            got = [(i.name, i.type, i.shape) for i in ins]
            raise CheckpointError(f"{d / 'audio.onnx'}: expected one float32 input 'waveform' of shape (n, T), got {got}")
        fixed = ins[0].shape[1] if isinstance(ins[0].shape[1], int) else None
        if fixed != info["clip_samples"]:
            raise CheckpointError(
                f"{d / 'audio.onnx'}: expected waveform length {info['clip_samples'] or 'dynamic'} "
                f"({AUDIO_MANIFEST} clip_samples), the graph takes {fixed or 'dynamic'}"
            )
        out_dim = outs[0].shape[-1] if outs and len(outs[0].shape) == 2 else None
        if out_dim != info["embed_dim"]:
            raise CheckpointError(
                f"{d / 'audio.onnx'}: expected an (n, {info['embed_dim']}) output ({AUDIO_MANIFEST} embed_dim), "
                f"got {outs[0].shape if outs else None}"
            )
        if expected_dim is not None and int(expected_dim) != info["embed_dim"]:
            raise CheckpointError(
                f"{d}: expected audio embeddings of the map encoder's size {expected_dim}, "
                f"this audio encoder outputs {info['embed_dim']}"
            )
        self.folder = d
        self.info = info
        self.sample_rate: int = info["sample_rate"]
        self._dim = info["embed_dim"]
        self._clip = info["clip_samples"]

    @staticmethod
    def _read_manifest(path: Path) -> dict:
        try:
            info = json.loads(path.read_text())
            if info.get("format") != _FORMAT:
                raise ValueError(f"format is {info.get('format')!r}, expected {_FORMAT!r}")
            if int(info.get("version", 0)) > _VERSION:
                raise ValueError(f"version {info['version']} is newer than {_VERSION}")
            info["sample_rate"] = int(info["sample_rate"])
            info["embed_dim"] = int(info["embed_dim"])
            info["clip_samples"] = None if info.get("clip_samples") is None else int(info["clip_samples"])
            if info["sample_rate"] <= 0 or info["embed_dim"] <= 0:
                raise ValueError("sample_rate and embed_dim must be positive")
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise CheckpointError(f"{path}: expected an audio encoder manifest, could not read it: {exc}") from exc
        return info

    @property
    def dim(self) -> int:
        return self._dim

    def encode_audio(self, waveforms: Sequence[np.ndarray], sample_rate: int) -> np.ndarray:
        """Embed mono clips (see :func:`check_waveforms` for what is accepted).

        Shape:
            n clips (n_samples_i,) -> (n, d) float32, unit rows.
        """
        clips = check_waveforms(waveforms, sample_rate, self.sample_rate)
        if self._clip is not None:
            clips = [_fit(w, self._clip) for w in clips]
        out = np.empty((len(clips), self._dim), np.float64)
        by_len: dict[int, list[int]] = {}
        for i, w in enumerate(clips):
            by_len.setdefault(len(w), []).append(i)
        for rows in by_len.values():
            batch = np.stack([clips[i] for i in rows])
            res = np.asarray(self._session.run(None, {"waveform": batch})[0], np.float64)
            if res.shape != (len(rows), self._dim) or not np.all(np.isfinite(res)):
                raise RuntimeError(f"{self.folder / 'audio.onnx'}: returned {res.shape} with non-finite values or the wrong size")
            out[rows] = res
        return unit_rows(out)


def export_audio_onnx(
    module,
    out_dir: str | Path,
    *,
    sample_rate: int,
    embed_dim: int,
    clip_samples: int | None = None,
    aligned_to: str = "",
    opset: int = 17,
) -> Path:
    """Write a torch module mapping (n, T) float32 waveforms to (n, d) in the folder layout.

    Args:
        module: ``torch.nn.Module`` taking one (n, T) float32 tensor.
        out_dir: folder to write (created).
        sample_rate: the rate (Hz) the module expects.
        embed_dim: the module's output size ``d``.
        clip_samples: fixed input length T, or ``None`` for any length.
        aligned_to: free text naming the encoder whose space the embeddings share.
        opset: ONNX opset version.

    Returns:
        ``out_dir`` as a ``Path``.
    """
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - torch is installed by the install line
        raise MissingDependencyError('exporting an audio encoder needs torch: pip install "conceptfusion-harness[torch]"') from exc
    from conceptfusion.io_utils import atomic_write_bytes, atomic_write_text

    if isinstance(sample_rate, bool) or not isinstance(sample_rate, numbers.Integral) or sample_rate <= 0:
        raise ValueError(f"sample_rate: expected a positive int in Hz, got {sample_rate!r}")
    if clip_samples is not None and (not isinstance(clip_samples, numbers.Integral) or clip_samples <= 0):
        raise ValueError(f"clip_samples: expected None or a positive int, got {clip_samples!r}")
    length = int(clip_samples) if clip_samples is not None else int(sample_rate) // 10
    dummy = torch.zeros(2, length)
    axes = {"waveform": {0: "n"} if clip_samples is not None else {0: "n", 1: "T"}, "embedding": {0: "n"}}
    buf = io.BytesIO()
    with warnings.catch_warnings():  # the TorchScript exporter warns about deprecation and tracing
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module.eval(), (dummy,), buf, input_names=["waveform"], output_names=["embedding"],
            dynamic_axes=axes, opset_version=opset, dynamo=False,
        )
    out = Path(out_dir)
    atomic_write_bytes(out / "audio.onnx", buf.getvalue())
    manifest = {
        "format": _FORMAT,
        "version": _VERSION,
        "sample_rate": int(sample_rate),
        "embed_dim": int(embed_dim),
        "clip_samples": None if clip_samples is None else int(clip_samples),
        "aligned_to": aligned_to,
    }
    atomic_write_text(out / AUDIO_MANIFEST, json.dumps(manifest, indent=2, sort_keys=True))
    return out
