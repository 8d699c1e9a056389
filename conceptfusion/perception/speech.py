"""Spoken queries without an audio-language model: offline speech recognition, then text.

No audio-language model (CLAP, AudioCLIP, wav2clip) ships offline, so the embedded audio
path recognises the spoken words with PocketSphinx's US-English acoustic model, constrained
by a grammar to the phrases a map can answer (its vocabulary), and embeds the recognised
phrase with the text tower.

The decoder may stop inside a phrase ("red" for "red mug"); such a partial result is
completed to the one vocabulary phrase that starts with it, and rejected when several do.
Clips are padded with 0.3 s of silence on both ends before decoding.

What it can do: turn a clearly spoken name from the vocabulary ("red mug", "teddy bear")
into the same query vector as typing it. What it cannot do: understand sounds that are not
speech (a dog barking, a kettle), free-form sentences, other languages, or words outside
the vocabulary or PocketSphinx's pronunciation dictionary — those phrases are dropped from
the grammar with a warning. For sound-to-concept queries, plug in an audio encoder
(:mod:`conceptfusion.perception.audio`).
"""

from __future__ import annotations

import logging
import re
from typing import Sequence

import numpy as np

from conceptfusion.errors import MissingDependencyError

__all__ = ["SpeechQueryEncoder", "SPEECH_SAMPLE_RATE"]

logger = logging.getLogger(__name__)

SPEECH_SAMPLE_RATE = 16000
"""Sample rate (Hz) of PocketSphinx's US-English acoustic model."""


def _decoder():
    try:
        from pocketsphinx import Decoder
    except ImportError as exc:
        raise MissingDependencyError(
            'spoken queries need PocketSphinx: pip install "conceptfusion-harness[audio]"'
        ) from exc
    return Decoder(loglevel="FATAL")


class SpeechQueryEncoder:
    """Spoken phrases from a fixed vocabulary to text-tower query vectors.

    Args:
        text_encoder: the text tower queries are embedded with (``encode_text``, ``dim``).
        vocabulary: phrases the recogniser may hear, e.g. the map's object names.
    """

    sample_rate = SPEECH_SAMPLE_RATE

    def __init__(self, text_encoder, vocabulary: Sequence[str]) -> None:
        self._text = text_encoder
        self._decoder = _decoder()
        phrases, dropped = [], []
        for raw in vocabulary:
            words = re.findall(r"[a-z']+", str(raw).lower())
            if words and all(self._decoder.lookup_word(w) is not None for w in words):
                phrase = " ".join(words)
                if phrase not in phrases:
                    phrases.append(phrase)
            else:
                dropped.append(raw)
        if dropped:
            logger.warning("speech vocabulary: dropped %d phrase(s) with unknown words: %s", len(dropped), dropped[:10])
        if not phrases:
            raise ValueError(
                "vocabulary: expected at least one phrase made of dictionary words, "
                f"got none usable out of {len(vocabulary)}"
            )
        self.vocabulary: tuple[str, ...] = tuple(phrases)
        grammar = "#JSGF V1.0;\ngrammar query;\npublic <query> = " + " | ".join(phrases) + ";\n"
        self._decoder.add_jsgf_string("query", grammar)
        self._decoder.activate_search("query")

    @property
    def dim(self) -> int:
        return int(self._text.dim)

    def _pcm16(self, waveform, sample_rate: int, index: int) -> bytes:
        if sample_rate != self.sample_rate:
            raise ValueError(
                f"waveforms: expected audio at {self.sample_rate} Hz, got {sample_rate} Hz (resample it first)"
            )
        w = np.asarray(waveform)
        if w.ndim != 1 or w.size == 0:
            raise ValueError(f"waveforms[{index}]: expected a non-empty mono (n_samples,) array, got shape {w.shape}")
        if w.dtype == np.int16:
            return w.tobytes()
        if w.dtype.kind != "f":
            raise TypeError(f"waveforms[{index}]: expected int16 PCM or float in [-1, 1], got {w.dtype}")
        if not np.all(np.isfinite(w)):
            raise ValueError(f"waveforms[{index}]: expected finite samples, found NaN or inf")
        return (np.clip(w, -1.0, 1.0) * 32767.0).astype(np.int16).tobytes()

    def transcribe(self, waveform, sample_rate: int) -> str | None:
        """The vocabulary phrase heard in ``waveform``, or ``None`` if nothing was recognised.

        Shape:
            ``waveform`` (n_samples,) int16 or float in [-1, 1].
        """
        pad = bytes(2 * int(0.3 * self.sample_rate))  # silence around the clip helps the endpointer
        pcm = pad + self._pcm16(waveform, sample_rate, 0) + pad
        self._decoder.start_utt()
        self._decoder.process_raw(pcm, full_utt=True)
        self._decoder.end_utt()
        hyp = self._decoder.hyp()
        text = " ".join(hyp.hypstr.split()) if hyp is not None else ""
        if not text:
            return None
        if text in self.vocabulary:
            return text
        # The search can stop inside a phrase ("red" for "red mug"): complete it when exactly
        # one vocabulary phrase starts with the words heard.
        matches = [p for p in self.vocabulary if (p + " ").startswith(text + " ")]
        return matches[0] if len(matches) == 1 else None

    def encode_audio(self, waveforms: Sequence[np.ndarray], sample_rate: int) -> np.ndarray:
        """Query vectors of spoken phrases; raises ``ValueError`` naming any clip not recognised.

        Shape:
            n waveforms (n_samples,) -> (n, d) float32.
        """
        texts = []
        for i, w in enumerate(waveforms):
            self._pcm16(w, sample_rate, i)
            text = self.transcribe(w, sample_rate)
            if text is None:
                raise ValueError(f"waveforms[{i}]: no vocabulary phrase was recognised (vocabulary: {self.vocabulary[:5]}...)")
            texts.append(text)
        return np.asarray(self._text.encode_text(texts), np.float32)
