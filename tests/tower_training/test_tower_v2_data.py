"""Tower v2 data: captions of library instances, table arrangements by split role, a few rendered
views whose crops hold no held-out (test) instance or category, and the multi-caption loss."""

import math

import numpy as np
import pytest

from sim_envs.assets.library import catalogue, get_instance
from sim_envs.scenes.splits import splits
from tower_training.captions import article, caption_bank, instance_captions
from tower_training.data import BACKGROUND_CLASS, SCENE_CLASS, SOURCES
from tower_training.library_views import TABLE, arrange_table, pool_for_seed_role
from tower_training.world_v2 import SPECIAL_CLASSES, DataConfigV2, render_crop_data_v2, train_caption_bank


def test_captions_of_an_instance_cover_every_kind():
    inst = get_instance("mug-000")
    caps = instance_captions(inst, catalogue())
    by_kind = {}
    for c in caps:
        by_kind.setdefault(c.kind, []).append(c.text)
    assert by_kind["name"] == ["mug", "a mug"]
    assert by_kind["synonym"] == ["coffee mug", "cup", "tea mug"]
    assert by_kind["parent"] == ["drinkware", "container"]  # the root "object" says nothing
    assert by_kind["colour"] == [f"a {inst.color} mug"]
    assert by_kind["material"] == [article(f"{inst.material} mug")]
    assert by_kind["function"] == ["something to drink from", "a cup for hot coffee or tea"]
    assert len({c.text for c in caps}) == len(caps)
    assert article("apple") == "an apple" and article("mug") == "a mug"


def test_caption_bank_shares_texts_and_marks_positives():
    bank = caption_bank([("a", instance_captions(get_instance("mug-000"), catalogue())),
                         ("b", instance_captions(get_instance("mug-001"), catalogue()))])
    assert bank.texts.count("mug") == 1
    t = bank.texts.index("mug")
    assert bank.positives[:, t].tolist() == [True, True]
    assert "mug" in bank.of("b")


def test_training_bank_holds_only_train_instances_and_no_held_out_category_name():
    split = splits()
    bank = train_caption_bank(split)
    assert set(bank.class_names[:-4]) == set(split.instances_of("train"))
    assert bank.class_names[-4:] == tuple(c.name for c in SPECIAL_CLASSES)
    assert bank.class_names[-4:-2] == (BACKGROUND_CLASS.name, SCENE_CLASS.name)
    held = set(split.categories_of("val")) | set(split.categories_of("test"))
    for name in held:
        assert name not in bank.texts and article(name) not in bank.texts


def test_pools_follow_the_split_roles():
    split = splits()
    train, val = pool_for_seed_role(split, "tower_train"), pool_for_seed_role(split, "tower_val")
    assert {split.instances[i] for i in train} == {"train"}
    assert {split.instances[i] for i in val} == {"val"}
    test_cats = set(split.categories_of("test"))
    assert not test_cats & {get_instance(i).category for i in train + val}
    assert set(split.categories_of("val")) <= {get_instance(i).category for i in val}
    cal = pool_for_seed_role(split, "calibration")
    assert "test" not in {split.instances[i] for i in cal}
    with pytest.raises(ValueError, match="seed_role"):
        pool_for_seed_role(split, "training")


def test_arrangements_are_seeded_on_the_table_and_from_the_pool():
    pool = pool_for_seed_role(splits(), "tower_train")
    a, b = arrange_table(100_003, pool), arrange_table(100_003, pool)
    assert a.to_json() == b.to_json()
    assert 1 <= len(a.objects) <= 8
    counts = [len(arrange_table(s, pool).objects) for s in range(100_000, 100_010)]
    assert min(counts) >= 3 and max(counts) <= 8
    for o in a.objects:
        assert o.asset.split(":", 1)[1] in pool
        assert abs(o.position[2] - TABLE.top_z) < 1e-9
        assert abs(o.position[0]) <= TABLE.size[0] / 2 and abs(o.position[1]) <= TABLE.size[1] / 2
    with pytest.raises(ValueError, match="n_objects"):
        arrange_table(1, pool, n_objects=(0, 2))


def test_a_few_views_give_crops_of_train_or_val_instances_only():
    split = splits()
    cfg = DataConfigV2(train_scenes=2, val_scenes=1, test_scenes=0, views_per_scene=1, width=160, height=120)
    data = render_crop_data_v2(cfg)
    cat = catalogue()
    names = np.array(data.class_names)[data.labels]
    obj = np.isin(data.sources, [SOURCES.index("gt"), SOURCES.index("proposer")])
    assert obj.any() and (names[data.sources == SOURCES.index("frame")] == SCENE_CLASS.name).sum() == 3
    train = np.isin(data.seeds, cfg.seeds("train", split))
    val = np.isin(data.seeds, cfg.seeds("val", split))
    assert (train | val).all() and train.any() and val.any()
    assert {split.instances[n] for n in names[obj & train]} == {"train"}
    assert {split.instances[n] for n in names[obj & val]} == {"val"}
    test_cats = set(split.categories_of("test"))
    assert not {cat.instances[n].category for n in names[obj]} & test_cats


def test_multicaption_loss_masks_other_positives_from_the_negatives():
    torch = pytest.importorskip("torch")
    from tower_training.training import multicaption_loss

    logits = torch.tensor([[2.0, 0.0, 1.0]])
    pos = torch.tensor([[True, False, True]])
    # caption 0 against {0, 1}; caption 2 against {2, 1}: caption 0 and 2 never compete
    want = -0.5 * ((2 - math.log(math.exp(2) + 1)) + (1 - math.log(math.exp(1) + 1)))
    assert float(multicaption_loss(logits, pos)) == pytest.approx(want, rel=1e-6)
    w = torch.tensor([3.0, 1.0, 1.0])
    want_w = -((3 * (2 - math.log(math.exp(2) + 1))) + (1 - math.log(math.exp(1) + 1))) / 4
    assert float(multicaption_loss(logits, pos, w)) == pytest.approx(want_w, rel=1e-6)


def test_onnx_weights_load_into_a_torch_tower_exactly():
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    import onnxruntime as ort

    from conceptfusion.perception.image_tower import SHIPPED_TOWER_DIR, TowerConfig, build_tower, preprocess
    from tower_training.training import load_tower_weights_from_onnx

    model = build_tower(TowerConfig(stem_stride=2))
    load_tower_weights_from_onnx(model, SHIPPED_TOWER_DIR / "tower.onnx")
    x = preprocess([np.random.default_rng(0).integers(0, 255, (30, 40, 3), dtype=np.uint8)], 64)
    want = ort.InferenceSession(str(SHIPPED_TOWER_DIR / "tower.onnx")).run(None, {"images": x})[0]
    with torch.no_grad():
        got = model.eval()(torch.from_numpy(x)).numpy()
    assert np.abs(got - want).max() < 1e-5


def test_topk_counts_a_correct_text_among_the_k_best():
    from tower_training.evaluate_v2 import topk

    emb = np.array([[1.0, 0.0], [0.0, 1.0]])
    texts = np.array([[1.0, 0.0], [0.6, 0.8], [0.0, 1.0]])
    ok = np.array([[False, True, False], [False, True, False]])
    assert topk(emb, texts, ok, 1) == 0.0  # each row's best text is the wrong one
    assert topk(emb, texts, ok, 2) == 1.0
    assert math.isnan(topk(np.zeros((0, 2)), texts, np.zeros((0, 3), bool)))


def test_room_views_show_train_instances_from_a_base_height_on_free_floor():
    from tower_training.room_views import RoomViewConfig, random_room_views
    from tower_training.world_v2 import RoomDataConfig

    split = splits()
    cfg = RoomViewConfig(width=160, height=120)
    seeds = RoomDataConfig(scenes=1).scene_seeds(split)
    views = list(random_room_views(seeds, 4, np.random.default_rng(0), cfg))
    again = list(random_room_views(seeds, 4, np.random.default_rng(0), cfg))
    assert len(views) == 4
    assert all(np.array_equal(a.frame.rgb, b.frame.rgb) for a, b in zip(views, again))  # seeded
    seen = set()
    for v in views:
        eye = v.frame.cam_to_world[:3, 3]
        assert cfg.eye_height_m[0] - 1e-6 <= eye[2] <= cfg.eye_height_m[1] + 1e-6
        seg = v.frame.segmentation
        seen |= {v.object_names[i] for i in np.unique(seg[seg >= 0])}
    assert seen, "no view shows any object"
    assert {split.instances[i] for i in views[0].object_names} == {"train"}


def test_room_seeds_must_lie_in_their_role():
    from sim_envs.scenes.splits import SplitError
    from tower_training.world_v2 import ROOM_TEST, RoomDataConfig

    split = splits()
    assert all(split.seed_role(s) == "evaluation" for s in ROOM_TEST.scene_seeds(split))
    with pytest.raises(SplitError, match="outside the tower_train range"):
        RoomDataConfig(seed0=149_990, scenes=20).scene_seeds(split)
    with pytest.raises(SplitError, match="outside the evaluation range"):
        RoomDataConfig(seed0=100_000, scenes=1, role="evaluation").scene_seeds(split)


def test_crop_data_concat_reindexes_labels_by_class_name():
    from tower_training.data import CropData

    img = np.zeros((4, 4, 3), np.uint8)
    a = CropData([img, img], np.array([0, 1]), np.array([0, 0]), np.array([1, 1]), np.array([0, 1]), ("x", "y"))
    b = CropData([img], np.array([1]), np.array([2]), np.array([7]), np.array([0]), ("z", "x"))
    c = CropData.concat([a, b])
    assert c.class_names == ("x", "y", "z")
    assert [c.class_names[l] for l in c.labels] == ["x", "y", "x"]
    assert c.views.tolist() == [0, 1, 2] and c.seeds.tolist() == [1, 1, 7] and c.sources.tolist() == [0, 0, 2]
    with pytest.raises(ValueError, match="at least one"):
        CropData.concat([])


def test_low_res_augmentation_shrinks_and_is_off_by_default():
    from tower_training.training import augment, shrink

    img = np.random.default_rng(0).integers(0, 255, (40, 60, 3), dtype=np.uint8)
    assert shrink(img, 2.0).shape == (20, 30, 3)
    assert shrink(img, 100.0).shape == (2, 2, 3)
    assert shrink(img, 1.0) is img
    # p = 0 draws nothing extra from the generator: the v1 recipe's crops are unchanged
    r1, r2 = np.random.default_rng(3), np.random.default_rng(3)
    assert np.array_equal(augment(img, r1), augment(img, r2, low_res_p=0.0))
    small = [augment(img, np.random.default_rng(s), low_res_p=1.0, low_res_scale=(3.0, 3.0)).shape[0] for s in range(5)]
    assert max(small) <= 15  # 40 / 3, then the random crop can only cut


def test_half_res_halves_every_crop():
    from tower_training.training import half_res

    crops = [np.zeros((40, 30, 3), np.uint8), np.zeros((3, 5, 3), np.uint8)]
    assert [c.shape for c in half_res(crops)] == [(20, 15, 3), (2, 2, 3)]


def test_room_crops_carry_the_room_background_and_scene_labels():
    from types import SimpleNamespace

    from conceptfusion.frames import RGBDFrame
    from tower_training.data import ROOM_BACKGROUND_CLASS, ROOM_SCENE_CLASS, ObjectClass, build_crop_data

    h, w = 40, 60
    seg = -np.ones((h, w), np.int32)
    seg[5:15, 5:15] = 0  # one object
    frame = RGBDFrame(rgb=np.full((h, w, 3), 128, np.uint8), depth=np.ones((h, w), np.float32),
                      K=np.array([[50.0, 0, w / 2], [0, 50.0, h / 2], [0, 0, 1]]), cam_to_world=np.eye(4), segmentation=seg)
    wall = np.zeros((1, h, w), bool)
    wall[0, 20:38, 20:58] = True  # a mask on no object
    view = SimpleNamespace(frame=frame, scene_seed=140_000, object_names=("mug-001",))
    proposer = SimpleNamespace(propose=lambda rgb, depth, K: np.concatenate([seg[None] == 0, wall]))
    classes = [ObjectClass("mug-001", ("a mug",)), ROOM_BACKGROUND_CLASS, ROOM_SCENE_CLASS, BACKGROUND_CLASS, SCENE_CLASS]
    data = build_crop_data([view], classes, np.random.default_rng(0), proposer=proposer,
                           background_class=ROOM_BACKGROUND_CLASS, scene_class=ROOM_SCENE_CLASS)
    names = np.array(data.class_names)[data.labels]
    assert names[data.sources == SOURCES.index("background")].tolist() == [ROOM_BACKGROUND_CLASS.name]
    assert names[data.sources == SOURCES.index("frame")].tolist() == [ROOM_SCENE_CLASS.name]
    assert set(names[data.sources < 2]) == {"mug-001"}


def test_room_view_config_refuses_bad_ranges():
    from tower_training.room_views import RoomViewConfig

    with pytest.raises(ValueError, match="eye_height_m: expected a range"):
        RoomViewConfig(eye_height_m=(1.5, 1.0))
    with pytest.raises(ValueError, match="at least 16 pixels"):
        RoomViewConfig(width=8)
    with pytest.raises(ValueError, match="fovy_deg"):
        RoomViewConfig(fovy_deg=180.0)


def test_init_record_traces_the_chain_of_starting_weights(tmp_path):
    import hashlib
    import json

    from tower_training.train_v2 import init_record

    with pytest.raises(SystemExit, match="expected an exported tower folder holding tower.onnx"):
        init_record(tmp_path)
    (tmp_path / "tower.onnx").write_bytes(b"weights")
    prev = {"world": "v2", "command": "python -m tower_training.train --world v2 --out DIR",
            "init": {"tower_dir": "v1dir", "world": "v1"}}
    (tmp_path / "tower.json").write_text(json.dumps(prev))
    rec = init_record(tmp_path)
    assert rec["onnx_sha256"] == hashlib.sha256(b"weights").hexdigest()
    assert rec["world"].startswith("v2") and rec["command"] == prev["command"] and rec["init"] == prev["init"]
    (tmp_path / "tower.json").unlink()  # no metadata: an exported v1-style folder
    assert init_record(tmp_path)["world"].startswith("v1") and init_record(tmp_path)["command"] is None
