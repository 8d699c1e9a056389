"""The encoder registry: spec strings, nearest-name suggestions, cheap imports."""

import subprocess
import sys

import pytest

from conceptfusion.perception.registry import ENCODERS, describe_encoders, make_encoder, parse_encoder_spec
from conceptfusion.perception.encoders import ColorNameEncoder, Encoder


def test_color_builds_the_color_encoder():
    enc = make_encoder("color")
    assert isinstance(enc, ColorNameEncoder) and isinstance(enc, Encoder)
    assert make_encoder("  COLOR ").dim == enc.dim


def test_spec_parsing():
    assert parse_encoder_spec("hf:openai/clip-vit-base-patch32") == ("hf", "openai/clip-vit-base-patch32")
    assert parse_encoder_spec("onnx:/a/b:c") == ("onnx", "/a/b:c")
    assert parse_encoder_spec("minilm-text") == ("minilm-text", None)


def test_unknown_names_suggest_the_nearest():
    with pytest.raises(ValueError, match="unknown encoder 'colour'; did you mean 'color'"):
        make_encoder("colour")
    with pytest.raises(ValueError, match="did you mean 'minilm-text'"):
        make_encoder("minilm")
    with pytest.raises(ValueError, match="needs a prefix: hf:openai/clip-vit-base-patch32"):
        make_encoder("openai/clip-vit-base-patch32")
    with pytest.raises(TypeError, match="expected a string"):
        make_encoder(None)


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="'hf' needs hub id or dir"):
        make_encoder("hf:")
    with pytest.raises(ValueError, match="'onnx' needs dir"):
        make_encoder("onnx")
    with pytest.raises(ValueError, match="'color' takes no argument"):
        make_encoder("color:64")


def test_missing_folders_name_the_path(tmp_path):
    pytest.importorskip("tokenizers")
    with pytest.raises(FileNotFoundError, match="no-such-dir"):
        make_encoder(f"onnx:{tmp_path / 'no-such-dir'}")


def test_table_lists_every_name_with_a_description():
    assert {"color", "minilm-text", "hf", "onnx", "audio-onnx", "embedded"} <= set(ENCODERS)
    lines = describe_encoders()
    assert set(lines) == set(ENCODERS) and all(lines.values())


def test_importing_the_registry_loads_no_heavy_library():
    code = "import sys, conceptfusion.perception.registry; print(sorted({'torch', 'transformers', 'onnxruntime'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"
