"""The embedded image tower: LiT-style training, ONNX export, onnxruntime inference."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx", reason="exporting the tower needs the onnx package (dev extra)")

from conceptfusion.perception.encoders import COLOR_NAMES, ColorNameEncoder  # noqa: E402
from conceptfusion.perception.image_tower import EmbeddedEncoder, TowerConfig, export_tower_onnx, preprocess  # noqa: E402
from tower_training.training import CropSet, TrainConfig, augment, class_targets, retrieval_accuracy, train_tower  # noqa: E402

NAMES = ["red", "green", "blue", "yellow"]
TOWER = TowerConfig(embed_dim=32, input_size=32, widths=(8, 16, 32, 32), blocks_per_stage=1)


def _crops(n, seed):
    rng = np.random.default_rng(seed)
    images, labels = [], []
    for i in range(n):
        c = i % len(NAMES)
        h, w = rng.integers(8, 40, 2)
        img = np.empty((h, w, 3))
        img[:] = COLOR_NAMES[NAMES[c]]
        images.append(np.clip(img + rng.normal(0, 25, img.shape), 0, 255).astype(np.uint8))
        labels.append(c)
    return CropSet(images, np.array(labels))


def test_preprocess_pads_to_square_and_normalises():
    img = np.zeros((10, 30, 3), np.uint8)
    img[:, :10] = 255
    x = preprocess([img], 16)
    assert x.shape == (1, 3, 16, 16) and x.dtype == np.float32
    # padding rows (top and bottom) carry the crop's mean colour, not black
    mean_val = (255 / 3 / 255 - 0.485) / 0.229
    assert x[0, 0, 0, 8] == pytest.approx(mean_val, abs=0.05)


def test_augment_keeps_colour_and_shape_kind():
    rng = np.random.default_rng(0)
    img = np.zeros((20, 30, 3), np.uint8)
    img[:] = (200, 30, 30)
    out = augment(img, rng)
    assert out.dtype == np.uint8 and out.ndim == 3 and out.shape[0] <= 20 and out.shape[1] <= 30
    med = np.median(out.reshape(-1, 3), axis=0)
    assert med[0] > med[1] and med[0] > med[2]  # still red: hue is never changed


def test_train_export_and_run_through_onnxruntime(tmp_path):
    enc = ColorNameEncoder(dim=32)
    targets = class_targets(enc, [[n, f"a {n} object"] for n in NAMES])
    assert np.allclose(np.linalg.norm(targets, axis=1), 1.0, atol=1e-5)
    train = _crops(200, 0)
    test = _crops(60, 1)
    model = train_tower(train, targets, TrainConfig(steps=60, batch_size=32, tower=TOWER), log_every=0)

    def torch_embed(images):
        with torch.inference_mode():
            return model(torch.from_numpy(preprocess(images, TOWER.input_size))).numpy()

    acc = retrieval_accuracy(torch_embed, test, targets)
    assert acc > 0.9  # chance is 0.25
    export_tower_onnx(model, TOWER, tmp_path, metadata={"note": "test"})
    embedded = EmbeddedEncoder(tmp_path, enc)
    assert embedded.dim == 32 and embedded.info["note"] == "test"
    onnx_emb = embedded.encode_image(test.images)
    assert np.allclose(onnx_emb, torch_embed(test.images), atol=1e-4)
    assert retrieval_accuracy(embedded.encode_image, test, targets) == acc
    assert np.allclose(embedded.encode_text(["red"]), enc.encode_text(["red"]))


def test_tower_errors(tmp_path):
    enc = ColorNameEncoder(dim=32)
    with pytest.raises(FileNotFoundError, match="tower.onnx"):
        EmbeddedEncoder(tmp_path, enc)
    (tmp_path / "tower.onnx").write_bytes(b"not a graph")
    (tmp_path / "tower.json").write_text('{"config": {"embed_dim": 32, "input_size": 32, "widths": [8], "blocks_per_stage": 1}}')
    with pytest.raises(ValueError, match="not a loadable ONNX graph"):
        EmbeddedEncoder(tmp_path, enc)
    with pytest.raises(ValueError, match="embed_dim"):
        train_tower(_crops(8, 0), np.ones((4, 5), np.float32), TrainConfig(steps=1, tower=TOWER))
    with pytest.raises(ValueError, match="at least one phrase"):
        class_targets(enc, [["red"], []])
