"""Training crops for the embedded tower: labels, crop kinds, storage, rendered views."""

import numpy as np
import pytest

from tower_training.data import (
    BACKGROUND_CLASS,
    SCENE_CLASS,
    SOURCES,
    CropConfig,
    CropData,
    build_crop_data,
    crops_from_view,
    instance_classes,
)


def _view():
    """A 40x60 image: object 0 at rows 5-15, cols 5-20; object 1 at rows 20-35, cols 30-50."""
    rgb = np.zeros((40, 60, 3), np.uint8)
    seg = np.full((40, 60), -1, np.int32)
    seg[5:15, 5:20] = 0
    seg[20:35, 30:50] = 1
    rgb[seg == 0] = (200, 0, 0)
    rgb[seg == 1] = (0, 0, 200)
    return rgb, seg


def test_instance_classes_cover_every_colour_and_category():
    cls = instance_classes(["red", "blue"], {"mug": ("a coffee mug",), "can": ("a can of soda", "something to drink")})
    assert [c.name for c in cls] == ["blue can", "red can", "blue mug", "red mug"]
    assert cls[3].phrases == ("red mug", "a red mug", "a coffee mug")
    assert (cls[0].category, cls[0].color) == ("can", "blue")
    with pytest.raises(ValueError, match="at least one colour and one category"):
        instance_classes([], {"mug": ()})


def test_ground_truth_crops_are_padded_boxes_with_object_labels():
    rgb, seg = _view()
    rng = np.random.default_rng(0)
    cfg = CropConfig(pad_range=(0.0, 0.0), min_area_px=10)
    crops, labels, sources = crops_from_view(rgb, seg, [7, 3], rng, config=cfg)
    assert labels == [7, 3] and sources == [SOURCES.index("gt")] * 2
    assert crops[0].shape == (10, 15, 3) and crops[1].shape == (15, 20, 3)
    assert np.all(crops[0] == (200, 0, 0))
    # padding widens the box (10% of 10 rows = 1 row each side) and stays inside the image
    crops, _, _ = crops_from_view(rgb, seg, [7, 3], rng, config=CropConfig(pad_range=(0.1, 0.1), min_area_px=10))
    assert crops[0].shape == (12, 17, 3)
    # an object labelled -1 gives no crop; small objects give none either
    crops, labels, _ = crops_from_view(rgb, seg, [-1, 3], rng, config=cfg)
    assert labels == [3]
    crops, labels, _ = crops_from_view(rgb, seg, [7, 3], rng, config=CropConfig(min_area_px=200))
    assert labels == [3]


def test_proposer_masks_are_matched_by_iou_and_background_kept_apart():
    rgb, seg = _view()
    good = seg == 1
    half = np.zeros_like(good)
    half[5:15, 5:12] = True  # IoU 7/15 with object 0: below 0.5, not matched
    back = np.zeros_like(good)
    back[30:40, 0:20] = True  # no object pixels
    props = np.stack([good, half, back])
    crops, labels, sources = crops_from_view(rgb, seg, [7, 3], np.random.default_rng(0), proposal_masks_rhw=props,
                                             background_label=9, scene_label=10,
                                             config=CropConfig(min_area_px=10, pad_range=(0, 0)))
    kinds = [SOURCES[s] for s in sources]
    assert kinds == ["gt", "gt", "proposer", "background", "frame"]
    assert labels == [7, 3, 3, 9, 10]
    assert crops[2].shape == (15, 20, 3) and crops[3].shape == (10, 20, 3) and crops[4].shape == (40, 60, 3)


def test_crops_from_view_rejects_bad_input():
    rgb, seg = _view()
    with pytest.raises(ValueError, match=r"expected \(H, W, 3\) uint8"):
        crops_from_view(rgb.astype(np.float32), seg, [0, 1], np.random.default_rng(0))
    with pytest.raises(ValueError, match="expected the image's size"):
        crops_from_view(rgb, seg[:10], [0, 1], np.random.default_rng(0))
    with pytest.raises(ValueError, match="only 1 labels given"):
        crops_from_view(rgb, seg, [0], np.random.default_rng(0))


def test_large_crops_are_shrunk_keeping_aspect():
    rgb = np.zeros((200, 300, 3), np.uint8)
    seg = np.full((200, 300), -1, np.int32)
    seg[0:150, 0:300] = 0
    crops, _, _ = crops_from_view(rgb, seg, [0], np.random.default_rng(0), scene_label=1,
                                  config=CropConfig(pad_range=(0, 0), max_side=60, frame_side=30))
    assert crops[0].shape == (30, 60, 3) and crops[1].shape == (20, 30, 3)


def test_crop_data_round_trips_through_npz(tmp_path):
    rng = np.random.default_rng(1)
    images = [rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for h, w in [(3, 4), (5, 2), (7, 7)]]
    data = CropData(images, [0, 2, 1], [0, 1, 3], [10, 10, 11], [0, 0, 1], ("a", "b", "c"))
    back = CropData.load(data.save(tmp_path / "crops.npz"))
    assert back.class_names == ("a", "b", "c")
    assert all(np.array_equal(a, b) for a, b in zip(images, back.images))
    assert back.labels.tolist() == [0, 2, 1] and back.seeds.tolist() == [10, 10, 11]
    sub = back.subset(back.labels > 0)
    assert len(sub) == 2 and sub.views.tolist() == [0, 1]
    with pytest.raises(ValueError, match="expected 3 entries"):
        CropData(images, [0, 1], [0, 0, 0], [0, 0, 0], [0, 0, 0], ("a",))
    with pytest.raises(FileNotFoundError, match="expected a .npz file"):
        CropData.load(tmp_path / "missing.npz")


def test_rendered_views_give_labelled_crops_of_the_right_objects():
    from sim_envs.assets.objects import ASSETS, COLORS
    from tower_training.views import ViewConfig, random_tabletop_views

    rng = np.random.default_rng(0)
    views = list(random_tabletop_views([5], 2, rng, ViewConfig(width=160, height=120)))
    assert len(views) == 2
    v = views[0]
    f = v.frame
    assert f.rgb.shape == (120, 160, 3) and f.rgb.dtype == np.uint8 and f.depth.shape == (120, 160)
    assert f.segmentation.max() < len(v.object_names) and (f.segmentation >= 0).any()
    classes = instance_classes(list(COLORS), {a.category: a.phrases for a in ASSETS.values()})
    classes += [BACKGROUND_CLASS, SCENE_CLASS]
    data = build_crop_data(views, classes, rng, config=CropConfig(min_area_px=20))
    names = np.array(data.class_names)[data.labels]
    gt = data.sources == SOURCES.index("gt")
    assert set(names[gt]) <= set(v.object_names) and gt.sum() >= 2
    assert (names[data.sources == SOURCES.index("frame")] == SCENE_CLASS.name).sum() == 2
    with pytest.raises(ValueError, match="views_per_scene"):
        next(random_tabletop_views([5], 0, rng))
