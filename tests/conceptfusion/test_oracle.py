"""The privileged oracle: segmentation ids to text embeddings of names."""

import numpy as np
import pytest

from conceptfusion.perception.encoders import ColorNameEncoder
from conceptfusion.perception.oracle import OracleFeatures


def test_oracle_maps_ids_to_name_embeddings():
    enc = ColorNameEncoder()
    oracle = OracleFeatures(enc, {0: "red", 3: "blue"})
    assert oracle.privileged
    seg = np.array([[0, 3, -1], [7, 3, 0]])
    pf = oracle(seg)
    dense = pf.dense()
    assert np.allclose(dense[0, 0], enc.encode_text(["red"])[0])
    assert np.allclose(dense[0, 1], enc.encode_text(["blue"])[0])
    assert np.all(dense[0, 2] == 0) and np.all(dense[1, 0] == 0)  # background and unnamed id
    with pytest.raises(ValueError, match="at least one"):
        OracleFeatures(enc, {})
    with pytest.raises(TypeError, match="segmentation_hw"):
        oracle(np.zeros((2, 2), np.float32))
