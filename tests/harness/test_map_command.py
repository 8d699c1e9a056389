"""``cfharness map``: a folder of rendered box-scene frames (npz per frame, TUM RGB-D) becomes a map
file that ``cfharness view`` opens with the encoder and floor it records and that finds the red box;
a bad folder or flag exits 2 with one line naming the file or flag, and writes nothing."""

from __future__ import annotations

import re

import numpy as np
import pytest

from conceptfusion.map.persistence import load_map, read_map_meta
from conceptfusion.synthetic import tabletop_boxes
from harness.cli import main
from harness.viewer.server import ViewerServer
from tests.conceptfusion.test_frame_folders import BAD_FOLDERS, box_frames, write_npz_folder, write_tum_folder

RED_BOX = next(b for b in tabletop_boxes() if b.name == "red box")


def test_an_npz_folder_becomes_a_map_the_viewer_opens_and_asks(tmp_path, capsys):
    folder = write_npz_folder(tmp_path / "my_frames", box_frames())
    out = tmp_path / "maps" / "mine.map.npz"
    assert main(["map", str(folder), "--out", str(out), "--encoder", "color"]) == 0
    printed = capsys.readouterr().out
    fmap = load_map(out)
    assert f"fused 4 frames into {len(fmap)} points in " in printed and " frames/s); score floor none (tabletop)" in printed
    assert f"open it: cfharness view {out}" in printed
    assert fmap.frames_integrated == 4 and len(fmap) > 10_000
    assert read_map_meta(out) == {"encoder": "color", "proposer": "rgbd", "setting": "tabletop", "min_score": None,
                                  "lookup": "plain"}
    with ViewerServer(out) as server:  # no --encoder: the one the file records
        assert server.encoder_name == "color"
        answer = server.open_map(None).text("red box")
    assert answer["found"], answer
    median = np.asarray(answer["regions"][0]["median"])
    assert np.linalg.norm(median - np.asarray(RED_BOX.center)) < 0.06


def test_a_tum_folder_with_intrinsics_every_and_setting(tmp_path, capsys):
    folder = write_tum_folder(tmp_path / "rgbd_dataset", box_frames(), camera=None)
    K = box_frames()[0].K
    flags = ["--intrinsics", f"{K[0, 0]},{K[1, 1]},{K[0, 2]},{K[1, 2]}", "--every", "2", "--setting", "search", "--max-depth", "2.5"]
    out = tmp_path / "tum.map.npz"
    assert main(["map", str(folder), "--out", str(out), "--encoder", "color", *flags]) == 0
    assert "Fusing 2 frames (tum layout) from" in capsys.readouterr().out
    fmap = load_map(out)
    assert fmap.frames_integrated == 2 and fmap.config.max_depth == 2.5
    assert read_map_meta(out)["setting"] == "search"
    fused = box_frames()[::2]
    assert max(float(f.depth[np.isfinite(f.depth)].max()) for f in fused) > 3.0  # the floor reaches farther ...
    depth_in = [(fmap.points - f.cam_to_world[:3, 3]) @ f.cam_to_world[:3, 2] for f in fused]  # along each optical axis
    assert np.min(depth_in, axis=0).max() <= 2.5 + 0.01  # ... than any point fused


@pytest.mark.parametrize("case, make, error, message", BAD_FOLDERS, ids=[c[0] for c in BAD_FOLDERS])
def test_a_bad_folder_exits_2_naming_the_file_and_writes_nothing(tmp_path, capsys, case, make, error, message):
    folder, _ = make(tmp_path)
    out = tmp_path / "out" / "map.npz"
    assert main(["map", str(folder), "--out", str(out), "--encoder", "color"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cfharness map: ") and err.count("\n") == 1
    assert re.search(message, err), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("flags, message", [
    (["--every", "0"], r"--every: expected an integer >= 1, got 0"),
    (["--max-depth", "nan"], r"--max-depth: expected a positive number of metres, got nan"),
    (["--intrinsics", "500,500,320"], r"--intrinsics: expected four numbers fx,fy,cx,cy \(pixels\), got '500,500,320'"),
    (["--out", "map.ply"], r"--out: expected a map file path ending in \.npz, got 'map\.ply'"),
    (["--encoder", "colr"], r"unknown encoder 'colr'; did you mean 'color'"),
])
def test_bad_flags_exit_2_naming_the_flag_and_write_nothing(tmp_path, capsys, monkeypatch, flags, message):
    monkeypatch.chdir(tmp_path)
    folder = write_npz_folder(tmp_path / "frames", box_frames()[:1])
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["map", str(folder), "--encoder", "color", *flags]) == 2
    assert re.search(message, capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_out_that_is_a_folder_or_under_a_file_is_refused(tmp_path, capsys):
    folder = write_npz_folder(tmp_path / "frames", box_frames()[:1])
    (tmp_path / "taken.npz").mkdir()
    (tmp_path / "file").write_text("x")
    assert main(["map", str(folder), "--out", str(tmp_path / "taken.npz"), "--encoder", "color"]) == 2
    assert "is a folder; expected a map file path ending in .npz" in capsys.readouterr().err
    assert main(["map", str(folder), "--out", str(tmp_path / "file" / "m.npz"), "--encoder", "color"]) == 2
    assert "file is a file, so" in capsys.readouterr().err


def test_the_default_out_is_named_after_the_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    folder = write_npz_folder(tmp_path / "kitchen", box_frames()[:1])
    assert main(["map", str(folder), "--encoder", "color"]) == 0
    assert (tmp_path / "runs" / "maps" / "kitchen.map.npz").is_file()
    assert "map written to runs/maps/kitchen.map.npz" in capsys.readouterr().out
