"""The score-floor command line: ``--frames`` and ``--size`` reach the scan settings of either
world's calibration, bad values are refused naming what arrived, ``--dry-run`` writes nothing."""

from __future__ import annotations

import re

import pytest

import tower_training.evaluate as ev


def _fake_result():
    split = {"present_found": 0.7, "n_present": 10, "absent_rejected": 0.9, "n_absent": 50, "absent_found_without_floor": 0.2,
             "absent_rejected_same_parent": 0.8, "n_absent_same_parent": 5, "absent_rejected_same_colour": 0.8,
             "n_absent_same_colour": 5, "balanced_accuracy": 0.8, "missed_present": []}
    return {"score_floor": 0.25, "calibration": split, "validation": split}


@pytest.mark.parametrize("world", ["v1", "v2"])
def test_frames_and_size_reach_the_scan(monkeypatch, world, capsys):
    seen = {}

    def v1(config, *, encoder=None):
        seen["scan"] = config
        return _fake_result()

    def v2(config, *, encoder=None):
        seen["scan"] = config.scan
        return _fake_result()

    monkeypatch.setattr(ev, "calibrate_score_floor", v1)
    monkeypatch.setattr(ev, "calibrate_score_floor_v2", v2)
    monkeypatch.setattr(ev, "write_score_floor", lambda *a, **k: pytest.fail("--dry-run must not write"))
    assert ev.main(["--calibrate-floor", "--world", world, "--frames", "8", "--size", "320x240", "--dry-run"]) == 0
    scan = seen["scan"]
    assert (scan.frames, scan.width, scan.height) == (8, 320, 240)
    if world == "v1":  # the v1 scenes stay those of the default configuration
        assert scan.calibration_scenes == ev.FloorConfig().calibration_scenes
    assert "floor 0.250" in capsys.readouterr().out


@pytest.mark.parametrize("argv, match", [
    (["--size", "320"], r"--size: expected WIDTHxHEIGHT in pixels such as 320x240, got '320'"),
    (["--size", "0x240"], r"--size: expected WIDTHxHEIGHT"),
    (["--frames", "0"], r"--frames: expected at least 1, got 0"),
])
def test_bad_scan_settings_are_refused(argv, match, capsys):
    with pytest.raises(SystemExit):
        ev.main(["--calibrate-floor", *argv])
    assert re.search(match, capsys.readouterr().err)
