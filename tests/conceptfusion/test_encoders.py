"""The encoder protocol and the colour-name test encoder."""

import numpy as np
import pytest

from conceptfusion.perception.encoders import COLOR_NAMES, ColorNameEncoder, Encoder
from conceptfusion.errors import DtypeError, ShapeError


def test_colour_crops_match_their_names():
    enc = ColorNameEncoder()
    assert isinstance(enc, Encoder)
    names = ["red", "green", "blue", "yellow"]
    crops = [np.full((8, 8, 3), COLOR_NAMES[n], np.uint8) for n in names]
    img = enc.encode_image(crops)
    txt = enc.encode_text([f"the {n} thing" for n in names])
    assert img.shape == (4, 32) and np.allclose(np.linalg.norm(img, axis=1), 1.0, atol=1e-5)
    sim = img @ txt.T
    assert np.array_equal(sim.argmax(axis=1), np.arange(4))
    # a text without colour words is unrelated to every colour
    assert np.abs(enc.encode_text(["sofa"]) @ img.T).max() < 0.05
    # deterministic
    assert np.array_equal(ColorNameEncoder().encode_text(["grey mug"]), enc.encode_text(["gray mug"]))


def test_bad_encoder_inputs():
    enc = ColorNameEncoder()
    with pytest.raises(DtypeError, match="uint8"):
        enc.encode_image([np.zeros((4, 4, 3), np.float32)])
    with pytest.raises(ShapeError, match=r"\(h, w, 3\)"):
        enc.encode_image([np.zeros((4, 4), np.uint8)])
    with pytest.raises(ShapeError, match="one"):
        enc.encode_image(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(TypeError, match="single str"):
        enc.encode_text("red")
    with pytest.raises(ValueError, match="non-empty"):
        enc.encode_text([""])
    with pytest.raises(ValueError, match="dim"):
        ColorNameEncoder(dim=4)
