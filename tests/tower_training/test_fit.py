"""Training bundles and the device-agnostic fit: exact crop round trips, batches that do not depend
on the worker count, a resumed fit equal to an uninterrupted one, and clear errors for bad files."""

import numpy as np
import pytest
import torch

from conceptfusion.perception.image_tower import NORMALISED_LEVELS, TowerConfig, preprocess, square_crops
from tower_training import fit as fit_mod
from tower_training.bundle import Bundle, decode_crops, encode_crops, load_bundle, save_bundle
from tower_training.fit import FitConfig, fit, load_fit, step_batch
from tower_training.training import CropSet, TrainConfig, half_res, name_top1

TINY = TowerConfig(embed_dim=8, input_size=16, widths=(4, 8, 8, 8), stem_stride=2)


def _crops(rng, n):
    """Noisy crops of varied sizes (a few 1- and 2-pixel sides) whose colour says their class."""
    out, labels = [], []
    for i in range(n):
        h, w = int(rng.integers(1, 40)), int(rng.integers(2, 50))
        c = i % 3
        im = rng.integers(0, 60, (h, w, 3)).astype(np.uint8)
        im[..., c] += 150
        out.append(im)
        labels.append(c)
    return out, np.array(labels, np.int64)


def _bundle(seed=0):
    rng = np.random.default_rng(seed)
    ims, labels = _crops(rng, 30)
    caps = rng.normal(size=(5, 8)).astype(np.float32)
    caps /= np.linalg.norm(caps, axis=1, keepdims=True)
    pos = np.array([[1, 0, 0, 1, 0], [0, 1, 0, 0, 1], [0, 0, 1, 0, 0]], bool)
    val, truth = _crops(rng, 9)
    return Bundle(CropSet(ims, labels), caps, pos, np.array([2, 2, 2, 1, 1], np.float32), val, truth, caps[:3].copy(),
                  {"note": "synthetic"})


def test_bundle_round_trip_is_exact(tmp_path):
    b = _bundle()
    path = save_bundle(tmp_path / "b.npz", b)
    back = load_bundle(path)
    assert len(back.train.images) == 30 and all(np.array_equal(x, y) for x, y in zip(back.train.images, b.train.images))
    assert all(np.array_equal(x, y) for x, y in zip(back.val_images, b.val_images))
    assert np.array_equal(back.train.labels, b.train.labels) and np.array_equal(back.val_truth, b.val_truth)
    assert np.array_equal(back.positives_ct, b.positives_ct) and np.allclose(back.captions_td, b.captions_td)
    assert back.meta == {"note": "synthetic"}


def test_crop_codec_is_lossless_on_rendered_like_crops():
    rng = np.random.default_rng(3)
    ims = [rng.integers(0, 256, (h, w, 3)).astype(np.uint8) for h, w in [(1, 1), (2, 7), (96, 64), (33, 128)]]
    data, offsets = encode_crops(ims)
    assert offsets[0] == 0 and offsets[-1] == len(data) and len(offsets) == 5
    assert all(np.array_equal(a, b) for a, b in zip(decode_crops(data, offsets), ims))


def test_bundle_errors_name_the_file_and_what_is_wrong(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"expected a \.npz file at .*nope\.npz"):
        load_bundle(tmp_path / "nope.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match=r"other\.npz: expected a training bundle, missing arrays \['caption_weights_t'"):
        load_bundle(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"junk\.npz: not a training bundle"):
        load_bundle(tmp_path / "junk.npz")
    b = _bundle()
    with pytest.raises(ValueError, match=r"training labels must index the 3 classes"):
        Bundle(CropSet(b.train.images, b.train.labels + 1), b.captions_td, b.positives_ct, b.caption_weights_t,
               b.val_images, b.val_truth, b.names_td)
    with pytest.raises(ValueError, match=r"every class needs at least one positive caption"):
        Bundle(b.train, b.captions_td, np.zeros_like(b.positives_ct), b.caption_weights_t, b.val_images, b.val_truth,
               b.names_td)
    with pytest.raises(ValueError, match=r"crop 1: expected an \(h, w, 3\) uint8 image"):
        encode_crops([b.train.images[0], np.zeros((4, 4), np.uint8)])
    with pytest.raises(ValueError, match=r"crop offsets: expected increasing offsets"):
        decode_crops(np.zeros(10, np.uint8), np.array([0, 4, 3, 10]))


def test_preprocess_is_square_crops_then_the_level_table():
    rng = np.random.default_rng(1)
    ims, _ = _crops(rng, 6)
    small = square_crops(ims, 16)
    assert small.shape == (6, 16, 16, 3) and small.dtype == np.uint8
    x = preprocess(ims, 16)
    expected = (small.astype(np.float32) / 255.0 - np.array([0.485, 0.456, 0.406], np.float32)) / np.array(
        [0.229, 0.224, 0.225], np.float32)
    assert np.array_equal(x, expected.transpose(0, 3, 1, 2))
    assert np.array_equal(NORMALISED_LEVELS[small[0, 0, 0, 1], 1], x[0, 1, 0, 0])


def test_a_batch_depends_on_its_step_only():
    b = _bundle()
    tc = TrainConfig(batch_size=7, seed=4, tower=TINY, low_res_p=0.5)
    x3, y3 = step_batch(b.train.images, b.train.labels, tc, 3)
    step_batch(b.train.images, b.train.labels, tc, 2)  # no state carried from one batch to the next
    x3b, y3b = step_batch(b.train.images, b.train.labels, tc, 3)
    x4, _ = step_batch(b.train.images, b.train.labels, tc, 4)
    assert x3.shape == (7, 16, 16, 3) and np.array_equal(x3, x3b) and np.array_equal(y3, y3b)
    assert not np.array_equal(x3, x4)


def _config(steps, workers=0):
    return FitConfig(train=TrainConfig(steps=steps, batch_size=6, lr=1e-2, seed=0, tower=TINY, low_res_p=0.5),
                     select_every=2, workers=workers, device="cpu")


def test_fit_is_the_same_with_loader_workers_and_keeps_the_best_validation(tmp_path):
    torch.set_num_threads(1)
    b = _bundle()
    serial = fit(b, _config(4), tmp_path / "serial", log_every=0)
    pooled = fit(b, _config(4, workers=2), tmp_path / "pooled", log_every=0)
    for k, v in serial["state_dict"].items():
        assert torch.equal(v, pooled["state_dict"][k]), k
    h = serial["history"]
    assert [e["step"] for e in h["evals"]] == [2, 4]
    assert h["best_val"] == max(e["val"] for e in h["evals"])
    model, record = load_fit(tmp_path / "serial" / "fit.pt", TINY)
    # the file holds the best weights: recompute the validation score from them
    embed = lambda ims: model(torch.from_numpy(preprocess(ims, 16))).detach().numpy()  # noqa: E731
    score = name_top1(embed, [b.val_images, half_res(b.val_images)], b.val_truth, b.names_td)
    assert score == pytest.approx(h["best_val"], abs=1e-9)
    assert record["fit_config"]["train"]["steps"] == 4 and "state_dict" not in record
    with pytest.raises(ValueError, match=r"the fit's tower is .* expected"):
        load_fit(tmp_path / "serial" / "fit.pt", TowerConfig())


def test_an_interrupted_fit_resumes_to_the_uninterrupted_result(tmp_path, monkeypatch):
    torch.set_num_threads(1)
    b = _bundle()
    whole = fit(b, _config(6), tmp_path / "whole", log_every=0)

    real_loader = fit_mod._loader

    def crashing_loader(bundle, config, start):
        for k, batch in enumerate(real_loader(bundle, config, start)):
            if start + k == 3:  # dies after step 3's validation point (steps 1..2 saved at step 2)
                raise KeyboardInterrupt
            yield batch

    monkeypatch.setattr(fit_mod, "_loader", crashing_loader)
    with pytest.raises(KeyboardInterrupt):
        fit(b, _config(6), tmp_path / "cut", log_every=0)
    monkeypatch.setattr(fit_mod, "_loader", real_loader)
    resumed = fit(b, _config(6), tmp_path / "cut", resume=True, log_every=0)
    assert resumed["history"]["evals"] == whole["history"]["evals"]
    for k, v in whole["state_dict"].items():
        assert torch.equal(v, resumed["state_dict"][k]), k
    with pytest.raises(ValueError, match=r"--resume: .*last\.pt was written with other settings"):
        fit(b, _config(8), tmp_path / "cut", resume=True, log_every=0)


def test_fit_rejects_a_bundle_of_another_dimension(tmp_path):
    b = _bundle()
    cfg = FitConfig(train=TrainConfig(steps=1, batch_size=2, tower=TowerConfig(stem_stride=2)))
    with pytest.raises(ValueError, match=r"caption embeddings have dimension 8, the tower 384"):
        fit(b, cfg, tmp_path, log_every=0)
    with pytest.raises(FileNotFoundError, match=r"expected a fit\.pt file"):
        load_fit(tmp_path / "missing.pt")


def test_the_command_says_what_is_wrong_with_its_arguments(tmp_path):
    path = save_bundle(tmp_path / "b.npz", _bundle())
    with pytest.raises(SystemExit, match=r"--widths: expected comma-separated channel counts, got 'a,b'"):
        fit_mod.main([str(path), "--out", str(tmp_path / "o"), "--widths", "a,b"])
    with pytest.raises(SystemExit, match=r"--low-res-p: expected a probability in \[0, 1\], got 2.0"):
        fit_mod.main([str(path), "--out", str(tmp_path / "o"), "--low-res-p", "2"])
    if not torch.cuda.is_available():
        with pytest.raises(SystemExit, match=r"--device cuda: this torch .* sees no CUDA device"):
            fit_mod.main([str(path), "--out", str(tmp_path / "o"), "--device", "cuda"])
    with pytest.raises(FileNotFoundError, match=r"training bundle: expected a \.npz file"):
        fit_mod.main([str(tmp_path / "missing.npz"), "--out", str(tmp_path / "o")])
