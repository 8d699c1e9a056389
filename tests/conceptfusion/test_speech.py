"""Spoken queries through the offline recogniser (recordings made with espeak-ng)."""

import wave
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pocketsphinx", reason="spoken queries need the audio extra")

from conceptfusion.perception.encoders import ColorNameEncoder  # noqa: E402
from conceptfusion.perception.speech import SpeechQueryEncoder  # noqa: E402

DATA = Path(__file__).parent / "data"
VOCAB = ["red mug", "teddy bear", "yellow duck", "bottle of wine", "blue bowl", "xqzzy gadget"]


def _read(name):
    with wave.open(str(DATA / name)) as w:
        return np.frombuffer(w.readframes(w.getnframes()), np.int16), w.getframerate()


def test_spoken_phrases_become_the_typed_query():
    enc = ColorNameEncoder()
    speech = SpeechQueryEncoder(enc, VOCAB)
    assert "xqzzy gadget" not in speech.vocabulary  # unknown words are dropped
    audio, rate = _read("red_mug.wav")
    assert speech.transcribe(audio, rate) == "red mug"
    for gain in (0.5, 1.0, 1.5):  # float input and level changes
        assert speech.transcribe(audio.astype(np.float32) / 32768.0 * gain, rate) == "red mug"
    bear, _ = _read("teddy_bear.wav")
    emb = speech.encode_audio([audio, bear], rate)
    assert np.allclose(emb, enc.encode_text(["red mug", "teddy bear"]))


def test_speech_bad_input():
    speech = SpeechQueryEncoder(ColorNameEncoder(), VOCAB)
    audio, rate = _read("red_mug.wav")
    with pytest.raises(ValueError, match="expected audio at 16000 Hz, got 44100 Hz"):
        speech.encode_audio([audio], 44100)
    with pytest.raises(ValueError, match="mono"):
        speech.encode_audio([np.zeros((2, 100), np.float32)], rate)
    silence = np.zeros(rate, np.int16)
    with pytest.raises(ValueError, match="no vocabulary phrase was recognised"):
        speech.encode_audio([silence], rate)
    with pytest.raises(ValueError, match="at least one phrase"):
        SpeechQueryEncoder(ColorNameEncoder(), ["xqzzy"])
