"""The demo command: a real map built, queried, scored and written."""

from harness.cli import main
from conceptfusion.persistence import load_map


def test_demo_runs_and_scores_every_query(tmp_path, capsys):
    code = main(["demo", "--out", str(tmp_path), "--frames", "6", "--height", "60", "--width", "80"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "wrong" not in out
    fmap = load_map(tmp_path / "map.npz")
    assert len(fmap) > 1000 and fmap.frames_integrated == 6
    assert (tmp_path / "map_rgb.ply").stat().st_size > 0
    assert (tmp_path / "query_red.ply").exists()
