"""Audio-language encoders exported to ONNX, on tiny torch modules built here."""

import json
import shutil

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from conceptfusion.perception.audio import AudioEncoder, OnnxAudioEncoder, check_waveforms, export_audio_onnx  # noqa: E402
from conceptfusion.perception.registry import make_encoder  # noqa: E402
from conceptfusion.errors import CheckpointError, DtypeError, ShapeError  # noqa: E402

RATE = 16000
CLIP = 160
DIM = 8


class _FixedLength(torch.nn.Module):
    """A linear map of a fixed-length clip."""

    def __init__(self):
        super().__init__()
        torch.manual_seed(0)
        self.lin = torch.nn.Linear(CLIP, DIM)

    def forward(self, waveform):
        return self.lin(waveform)


class _AnyLength(torch.nn.Module):
    """Summary statistics of a clip of any length, then a linear map."""

    def __init__(self):
        super().__init__()
        torch.manual_seed(1)
        self.lin = torch.nn.Linear(3, DIM)

    def forward(self, waveform):
        stats = torch.stack([waveform.mean(1), (waveform * waveform).mean(1), waveform.abs().amax(1)], dim=1)
        return self.lin(stats)


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("audio")
    fixed = export_audio_onnx(_FixedLength(), root / "fixed", sample_rate=RATE, embed_dim=DIM, clip_samples=CLIP, aligned_to="test")
    dynamic = export_audio_onnx(_AnyLength(), root / "dynamic", sample_rate=RATE, embed_dim=DIM)
    return fixed, dynamic


def _clip(n, seed):
    return (np.random.default_rng(seed).uniform(-0.5, 0.5, n)).astype(np.float32)


def test_fixed_length_graph_pads_and_trims(folders):
    enc = OnnxAudioEncoder(folders[0])
    assert isinstance(enc, AudioEncoder) and enc.dim == DIM and enc.sample_rate == RATE
    short, long = _clip(100, 0), _clip(300, 1)
    e = enc.encode_audio([short, long], RATE)
    assert e.shape == (2, DIM) and e.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)
    padded = np.concatenate([short, np.zeros(60, np.float32)])
    np.testing.assert_allclose(enc.encode_audio([padded], RATE)[0], e[0], atol=1e-6)
    np.testing.assert_allclose(enc.encode_audio([long[70:230]], RATE)[0], e[1], atol=1e-6)
    # against torch directly
    with torch.no_grad():
        ref = _FixedLength()(torch.from_numpy(padded[None])).numpy()[0]
    np.testing.assert_allclose(e[0], ref / np.linalg.norm(ref), atol=1e-5)


def test_dynamic_length_graph_batches_by_length(folders):
    enc = OnnxAudioEncoder(folders[1])
    clips = [_clip(400, 2), _clip(900, 3), _clip(400, 4)]
    together = enc.encode_audio(clips, RATE)
    alone = np.concatenate([enc.encode_audio([c], RATE) for c in clips])
    np.testing.assert_allclose(together, alone, atol=1e-6)
    np.testing.assert_array_equal(together, enc.encode_audio(clips, RATE))
    assert not np.allclose(together[0], together[2])


def test_int16_pcm_is_scaled_like_float(folders):
    enc = OnnxAudioEncoder(folders[0])
    pcm = (np.random.default_rng(5).integers(-20000, 20000, CLIP)).astype(np.int16)
    np.testing.assert_allclose(
        enc.encode_audio([pcm], RATE), enc.encode_audio([pcm.astype(np.float32) / 32768.0], RATE), atol=1e-6
    )


def test_wrong_audio_is_refused(folders):
    enc = OnnxAudioEncoder(folders[0])
    with pytest.raises(ValueError, match="expected audio at 16000 Hz, got 44100 Hz"):
        enc.encode_audio([_clip(CLIP, 0)], 44100)
    with pytest.raises(TypeError, match="sample_rate: expected an int"):
        enc.encode_audio([_clip(CLIP, 0)], 16000.0)
    with pytest.raises(ShapeError, match=r"waveforms\[0\]: expected a non-empty mono"):
        enc.encode_audio([np.zeros((CLIP, 2), np.float32)], RATE)
    with pytest.raises(ShapeError, match="got one"):
        enc.encode_audio(_clip(CLIP, 0), RATE)
    with pytest.raises(DtypeError, match="float samples in \\[-1, 1\\] or int16"):
        enc.encode_audio([np.zeros(CLIP, np.int32)], RATE)
    bad = _clip(CLIP, 0)
    bad[3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        enc.encode_audio([bad], RATE)
    with pytest.raises(ValueError, match="at least one clip"):
        check_waveforms([], RATE, RATE)


def test_load_time_checks(tmp_path, folders):
    with pytest.raises(FileNotFoundError, match="no such folder"):
        OnnxAudioEncoder(tmp_path / "none")
    with pytest.raises(CheckpointError, match="expected audio embeddings of the map encoder's size 384"):
        OnnxAudioEncoder(folders[0], expected_dim=384)
    d = shutil.copytree(folders[0], tmp_path / "a")
    info = json.loads((d / "audio.json").read_text())
    (d / "audio.json").write_text(json.dumps({**info, "embed_dim": 16}))
    with pytest.raises(CheckpointError, match=r"expected an \(n, 16\) output"):
        OnnxAudioEncoder(d)
    (d / "audio.json").write_text(json.dumps({**info, "clip_samples": 320}))
    with pytest.raises(CheckpointError, match="expected waveform length 320"):
        OnnxAudioEncoder(d)
    (d / "audio.json").write_text(json.dumps(info))
    (d / "audio.onnx").write_bytes(b"\x00garbage")
    with pytest.raises(CheckpointError, match="loadable ONNX graph"):
        OnnxAudioEncoder(d)


def test_registry_builds_the_audio_encoder(folders):
    enc = make_encoder(f"audio-onnx:{folders[1]}")
    assert isinstance(enc, OnnxAudioEncoder) and enc.info["clip_samples"] is None
