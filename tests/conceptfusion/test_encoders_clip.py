"""Hugging Face and ONNX CLIP encoders on a tiny randomly initialised CLIP built here."""

import json
import shutil
import string

import numpy as np
import pytest

torch = pytest.importorskip("torch")
transformers = pytest.importorskip("transformers", reason="Hugging Face CLIP needs the perception extra")
pytest.importorskip("tokenizers", reason="ONNX CLIP needs the perception extra")

from conceptfusion.perception.clip_hf import ClipPreprocess, HFClipConfig, HFClipEncoder, clip_preprocess, read_preprocess_config  # noqa: E402
from conceptfusion.perception.clip_onnx import OnnxClipEncoder, export_clip_to_onnx  # noqa: E402
from conceptfusion.perception.registry import make_encoder  # noqa: E402
from conceptfusion.perception.encoders import Encoder  # noqa: E402
from conceptfusion.errors import CheckpointError, DtypeError, ShapeError  # noqa: E402

PROJ = 24
IMAGE = 32
TEXTS = ["a red mug", "mug", "a red red mug on a red mug", "red"]
MEAN = (0.5, 0.4, 0.3)
STD = (0.2, 0.25, 0.3)


def _tokenizer_files(folder):
    """A byte-pair vocabulary of single letters plus a few merges, with CLIP's special tokens."""
    vocab = {}
    for c in string.ascii_lowercase:
        vocab[c] = len(vocab)
    for c in string.ascii_lowercase:
        vocab[c + "</w>"] = len(vocab)
    merges = ["r e", "re d</w>", "m u", "mu g</w>", "o n</w>"]
    for m in merges:
        vocab[m.replace(" ", "")] = len(vocab)
    vocab["<|startoftext|>"] = len(vocab)
    vocab["<|endoftext|>"] = len(vocab)
    (folder / "vocab.json").write_text(json.dumps(vocab))
    (folder / "merges.txt").write_text("#version: 0.2\n" + "\n".join(merges) + "\n")
    return len(vocab), vocab["<|startoftext|>"], vocab["<|endoftext|>"]


def _build_tiny_clip(folder, *, preprocessor=True):
    folder.mkdir(parents=True, exist_ok=True)
    n_vocab, bos, eos = _tokenizer_files(folder)
    tok = transformers.CLIPTokenizer.from_pretrained(str(folder))
    cfg = transformers.CLIPConfig(
        text_config=dict(
            vocab_size=n_vocab, hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2,
            max_position_embeddings=16, bos_token_id=bos, eos_token_id=eos, pad_token_id=eos,
        ),
        vision_config=dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2, image_size=IMAGE, patch_size=8),
        projection_dim=PROJ,
    )
    torch.manual_seed(0)
    transformers.CLIPModel(cfg).eval().save_pretrained(str(folder))
    tok.save_pretrained(str(folder))
    if preprocessor:
        (folder / "preprocessor_config.json").write_text(json.dumps({
            "size": {"shortest_edge": IMAGE}, "crop_size": {"height": IMAGE, "width": IMAGE}, "do_center_crop": True,
            "image_mean": list(MEAN), "image_std": list(STD), "resample": 3,
        }))
    return folder


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("clip")
    hf_dir = _build_tiny_clip(root / "hf")
    onnx_dir = export_clip_to_onnx(hf_dir, root / "onnx")
    return hf_dir, onnx_dir, HFClipEncoder(hf_dir), OnnxClipEncoder(onnx_dir)


def _images():
    rng = np.random.default_rng(3)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for h, w in [(40, 60), (32, 32), (90, 17), (8, 8)]]


# --- preprocessing -----------------------------------------------------------------------


def test_preprocess_constant_image_is_normalised_exactly():
    img = np.full((20, 50, 3), (255, 0, 102), np.uint8)
    x = clip_preprocess([img], ClipPreprocess(crop_hw=(16, 16), shortest_edge=16, mean=MEAN, std=STD))
    assert x.shape == (1, 3, 16, 16) and x.dtype == np.float32
    expected = (np.array([1.0, 0.0, 0.4]) - MEAN) / STD
    np.testing.assert_allclose(x[0, :, 5, 7], expected, atol=1e-6)
    np.testing.assert_allclose(x[0].std(axis=(1, 2)), 0.0, atol=1e-6)


def test_preprocess_keeps_only_the_centre_crop():
    # 32 x 96 at shortest edge 32: no resize, the crop keeps columns 32..63
    img = np.zeros((32, 96, 3), np.uint8)
    img[:, 32:64] = 255
    x = clip_preprocess([img], ClipPreprocess(crop_hw=(32, 32), shortest_edge=32, mean=(0, 0, 0), std=(1, 1, 1)))
    assert np.all(x == 1.0)


def test_preprocess_matches_the_pil_image_processor():
    pil_clip = pytest.importorskip("transformers.models.clip.image_processing_pil_clip")
    rng = np.random.default_rng(0)
    for h, w, s in [(50, 70, 32), (300, 200, 64), (20, 25, 32), (31, 97, 16)]:
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        proc = pil_clip.CLIPImageProcessorPil(size={"shortest_edge": s}, crop_size={"height": s, "width": s})
        ref = proc(images=[img], return_tensors="np")["pixel_values"]
        mine = clip_preprocess([img], read_preprocess_config(None, s))
        assert mine.shape == ref.shape
        # PIL rounds its filter weights to fixed point: at most one grey level apart
        assert np.abs(mine - ref).max() <= 1.01 / 255 / 0.2613  # smallest OpenAI std


def test_read_preprocess_config_square_resize_without_crop():
    pre = read_preprocess_config({"size": {"height": 24, "width": 24}, "do_center_crop": False, "resample": 2}, 24)
    assert pre.resize_hw == (24, 24) and pre.shortest_edge is None and pre.crop_hw == (24, 24)
    assert pre.resample == "bilinear"
    x = clip_preprocess([np.zeros((10, 40, 3), np.uint8)], pre)
    assert x.shape == (1, 3, 24, 24)


# --- Hugging Face ------------------------------------------------------------------------


def test_hf_encoder_shapes_norms_and_determinism(tiny):
    _, _, hf, _ = tiny
    assert isinstance(hf, Encoder) and hf.dim == PROJ
    assert hf.preprocess.mean == MEAN and hf.preprocess.std == STD
    t = hf.encode_text(TEXTS)
    i = hf.encode_image(_images())
    assert t.shape == (len(TEXTS), PROJ) and i.shape == (4, PROJ)
    assert t.dtype == np.float32 and i.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(i, axis=1), 1.0, atol=1e-5)
    np.testing.assert_array_equal(t, hf.encode_text(TEXTS))
    np.testing.assert_array_equal(i, hf.encode_image(_images()))
    assert not np.allclose(t[0], t[1])


def test_hf_text_embedding_does_not_depend_on_batch_padding(tiny):
    hf_dir, _, hf, _ = tiny
    alone = hf.encode_text(["mug"])
    padded = hf.encode_text(["a red red mug on a red mug", "mug"])[1:]
    np.testing.assert_allclose(alone, padded, atol=1e-5)
    small_batches = HFClipEncoder(hf_dir, HFClipConfig(batch_size=1)).encode_text(TEXTS)
    np.testing.assert_allclose(small_batches, hf.encode_text(TEXTS), atol=1e-5)


def test_hf_without_preprocessor_config_uses_openai_values(tmp_path):
    enc = HFClipEncoder(_build_tiny_clip(tmp_path / "m", preprocessor=False))
    assert enc.preprocess.mean == pytest.approx((0.48145466, 0.4578275, 0.40821073))
    assert enc.preprocess.crop_hw == (IMAGE, IMAGE) and enc.preprocess.shortest_edge == IMAGE


def test_hf_bad_input_is_refused(tiny):
    _, _, hf, _ = tiny
    with pytest.raises(ValueError, match="non-empty"):
        hf.encode_text(["mug", "  "])
    with pytest.raises(TypeError, match="single str"):
        hf.encode_text("mug")
    with pytest.raises(DtypeError, match="uint8"):
        hf.encode_image([np.zeros((8, 8, 3), np.float32)])
    with pytest.raises(ShapeError, match=r"\(h, w, 3\)"):
        hf.encode_image([np.zeros((8, 8), np.uint8)])


def test_hf_missing_folder_names_the_path(tmp_path):
    missing = tmp_path / "nothing-here"
    with pytest.raises(FileNotFoundError, match="nothing-here.*expected a CLIP checkpoint folder"):
        HFClipEncoder(missing)
    with pytest.raises(FileNotFoundError, match="no such folder"):
        make_encoder(f"hf:{missing}")


def test_hf_folder_without_weights(tmp_path, tiny):
    d = shutil.copytree(tiny[0], tmp_path / "m")
    (d / "model.safetensors").unlink()
    with pytest.raises(CheckpointError, match="expected model weights"):
        HFClipEncoder(d)


def test_hf_corrupt_weights_file(tmp_path, tiny):
    d = shutil.copytree(tiny[0], tmp_path / "m")
    data = (d / "model.safetensors").read_bytes()
    (d / "model.safetensors").write_bytes(data[: len(data) // 3])
    with pytest.raises(CheckpointError, match=r"m \(local folder\).*could not load the model weights"):
        HFClipEncoder(d)


def test_hf_weights_that_do_not_match_the_config(tmp_path, tiny):
    d = shutil.copytree(tiny[0], tmp_path / "m")
    cfg = json.loads((d / "config.json").read_text())
    cfg["projection_dim"] = 16
    (d / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(CheckpointError, match="model weights|missing or mismatched"):
        HFClipEncoder(d)


def test_hf_checkpoint_missing_a_parameter_is_not_silently_reinitialised(tmp_path, tiny):
    safetensors_numpy = pytest.importorskip("safetensors.numpy")
    d = shutil.copytree(tiny[0], tmp_path / "m")
    weights = safetensors_numpy.load_file(str(d / "model.safetensors"))
    del weights["text_projection.weight"]
    safetensors_numpy.save_file(weights, str(d / "model.safetensors"), metadata={"format": "pt"})
    with pytest.raises(CheckpointError, match=r"1 missing or mismatched.*text_projection.weight"):
        HFClipEncoder(d)


def test_hf_refuses_a_model_that_is_not_clip(tmp_path, tiny):
    d = shutil.copytree(tiny[0], tmp_path / "m")
    (d / "config.json").write_text(json.dumps({"model_type": "bert", "hidden_size": 32}))
    with pytest.raises(CheckpointError, match="expected a CLIP-family checkpoint.*'bert'"):
        HFClipEncoder(d)


# --- ONNX --------------------------------------------------------------------------------


def test_onnx_layout_written_by_the_exporter(tiny):
    _, onnx_dir, _, _ = tiny
    assert sorted(p.name for p in onnx_dir.iterdir()) == ["clip_onnx.json", "image.onnx", "text.onnx", "tokenizer.json"]
    info = json.loads((onnx_dir / "clip_onnx.json").read_text())
    assert info["embed_dim"] == PROJ and info["max_length"] == 16
    assert info["preprocess"]["mean"] == list(MEAN)


def test_onnx_agrees_with_hf(tiny):
    _, _, hf, ox = tiny
    assert isinstance(ox, Encoder) and ox.dim == PROJ
    for key in ("input_ids", "attention_mask"):
        np.testing.assert_array_equal(ox.tokenize(TEXTS)[key], hf.tokenize(TEXTS)[key])
    t_onnx = ox.encode_text(TEXTS)
    i_onnx = ox.encode_image(_images())
    assert t_onnx.shape == (len(TEXTS), PROJ) and i_onnx.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(i_onnx, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(t_onnx, hf.encode_text(TEXTS), atol=1e-5)
    np.testing.assert_allclose(i_onnx, hf.encode_image(_images()), atol=1e-5)
    np.testing.assert_array_equal(t_onnx, ox.encode_text(TEXTS))


def test_onnx_truncates_long_texts_to_max_length(tiny):
    _, _, hf, ox = tiny
    long = " ".join(["mug"] * 40)
    ids = ox.tokenize([long])["input_ids"]
    assert ids.shape == (1, 16)
    np.testing.assert_allclose(ox.encode_text([long]), hf.encode_text([long]), atol=1e-5)


def test_onnx_bad_input_is_refused(tiny):
    ox = tiny[3]
    with pytest.raises(ValueError, match="non-empty"):
        ox.encode_text([""])
    with pytest.raises(DtypeError, match="uint8"):
        ox.encode_image([np.zeros((8, 8, 3), np.int64)])


def test_onnx_missing_folder_and_files(tmp_path, tiny):
    with pytest.raises(FileNotFoundError, match="no such folder"):
        OnnxClipEncoder(tmp_path / "none")
    d = shutil.copytree(tiny[1], tmp_path / "o")
    (d / "text.onnx").unlink()
    with pytest.raises(FileNotFoundError, match="missing text.onnx"):
        OnnxClipEncoder(d)


def _export_module(module, path, example, in_names, out_name):
    import io
    import warnings

    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module.eval(), example, buf, input_names=in_names, output_names=[out_name],
            dynamic_axes={in_names[0]: {0: "n"}, out_name: {0: "n"}}, opset_version=17, dynamo=False,
        )
    path.write_bytes(buf.getvalue())


class _FlatImage(torch.nn.Module):
    def __init__(self, dim):
        super().__init__()
        self.lin = torch.nn.Linear(3 * IMAGE * IMAGE, dim)

    def forward(self, pixel_values):
        return self.lin(pixel_values.flatten(1))


def test_onnx_graph_with_the_wrong_output_size(tmp_path, tiny):
    d = shutil.copytree(tiny[1], tmp_path / "o")
    _export_module(_FlatImage(16), d / "image.onnx", (torch.zeros(1, 3, IMAGE, IMAGE),), ["pixel_values"], "image_embeds")
    with pytest.raises(CheckpointError, match=f"expected both graphs to output {PROJ}-d.*image.onnx 16-d and text.onnx {PROJ}-d"):
        OnnxClipEncoder(d)


def test_onnx_graph_with_the_wrong_input(tmp_path, tiny):
    d = shutil.copytree(tiny[1], tmp_path / "o")
    _export_module(_FlatImage(PROJ), d / "image.onnx", (torch.zeros(1, 3, IMAGE, IMAGE),), ["images"], "image_embeds")
    with pytest.raises(CheckpointError, match="expected one float32 input 'pixel_values'"):
        OnnxClipEncoder(d)
    d2 = shutil.copytree(tiny[1], tmp_path / "o2")
    info = json.loads((d2 / "clip_onnx.json").read_text())
    info["preprocess"]["crop_hw"] = [48, 48]
    (d2 / "clip_onnx.json").write_text(json.dumps(info))
    with pytest.raises(CheckpointError, match=r"expected input shape \(n, 3, 48, 48\)"):
        OnnxClipEncoder(d2)


def test_onnx_corrupt_graph_and_manifest(tmp_path, tiny):
    d = shutil.copytree(tiny[1], tmp_path / "o")
    (d / "text.onnx").write_bytes(b"not a graph")
    with pytest.raises(CheckpointError, match="text.onnx: expected a loadable ONNX graph"):
        OnnxClipEncoder(d)
    d2 = shutil.copytree(tiny[1], tmp_path / "o2")
    (d2 / "clip_onnx.json").write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(CheckpointError, match="expected a manifest with format 'conceptfusion-clip-onnx'"):
        OnnxClipEncoder(d2)


# --- other CLIP-family models with the same API ------------------------------------------


_WORDS = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "<s>", "</s>", "<pad>", "red", "mug", "a", "\u7ea2", "\u676f"]


def _word_tokenizer(folder, cls, sep, pad):
    """A whole-word tokenizer with BERT- or XLM-R-style special tokens, written as tokenizer.json."""
    from tokenizers import Tokenizer, models, pre_tokenizers, processors

    vocab = {w: i for i, w in enumerate(_WORDS)}
    tok = Tokenizer(models.WordLevel(vocab, unk_token="[UNK]"))
    tok.pre_tokenizer = pre_tokenizers.Whitespace()
    tok.post_processor = processors.TemplateProcessing(
        single=f"{cls} $A {sep}", special_tokens=[(cls, vocab[cls]), (sep, vocab[sep])]
    )
    tok.save(str(folder / "tokenizer.json"))
    (folder / "tokenizer_config.json").write_text(
        json.dumps({"tokenizer_class": "PreTrainedTokenizerFast", "pad_token": pad, "unk_token": "[UNK]"})
    )


@pytest.mark.parametrize("family", ["altclip", "chinese_clip"])
def test_multilingual_families_load_and_export(tmp_path, family):
    vision = dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2, image_size=IMAGE, patch_size=8)
    text = dict(vocab_size=len(_WORDS), hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2)
    if family == "altclip":
        cfg = transformers.AltCLIPConfig(
            text_config=dict(text, project_dim=PROJ, pad_token_id=6, bos_token_id=4, eos_token_id=5),
            vision_config=vision, projection_dim=PROJ,
        )
        model, special = transformers.AltCLIPModel(cfg), ("<s>", "</s>", "<pad>")
    else:
        cfg = transformers.ChineseCLIPConfig(text_config=dict(text, pad_token_id=0), vision_config=vision, projection_dim=PROJ)
        model, special = transformers.ChineseCLIPModel(cfg), ("[CLS]", "[SEP]", "[PAD]")
    torch.manual_seed(0)
    model.eval().save_pretrained(str(tmp_path / "hf"))
    _word_tokenizer(tmp_path / "hf", *special)
    hf = HFClipEncoder(tmp_path / "hf")
    texts = ["a red mug", "\u7ea2 \u676f", "mug"]
    t = hf.encode_text(texts)
    assert t.shape == (3, PROJ)
    np.testing.assert_allclose(hf.encode_text(["mug"]), t[2:], atol=1e-5)  # padding does not leak
    ox = OnnxClipEncoder(export_clip_to_onnx(tmp_path / "hf", tmp_path / "onnx"))
    np.testing.assert_allclose(ox.encode_text(texts), t, atol=1e-5)
    np.testing.assert_allclose(ox.encode_image(_images()), hf.encode_image(_images()), atol=1e-5)


# --- the registry, with real checkpoints -------------------------------------------------


def test_registry_builds_hf_and_onnx_encoders(tiny):
    hf_dir, onnx_dir, hf, _ = tiny
    by_hf = make_encoder(f"hf:{hf_dir}")
    by_onnx = make_encoder(f"onnx:{onnx_dir}")
    assert isinstance(by_hf, HFClipEncoder) and isinstance(by_onnx, OnnxClipEncoder)
    np.testing.assert_allclose(by_onnx.encode_text(["mug"]), hf.encode_text(["mug"]), atol=1e-5)
