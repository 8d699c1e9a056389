"""``cfharness replay RUN EPISODE``, ``cfharness run --record`` and the videos ``cfharness report`` renders."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from harness.cli import main
from harness.replay.record import load_recording
from harness.replay.video import video_codec
from harness.report.paths import REPLAYS_DIR, replay_stem
from harness.runner.run import RunConfig, run_suites


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """Two agents on the same tabletop episode, both recorded."""
    run = tmp_path_factory.mktemp("run")
    config = RunConfig(suites=("regression-rearrange",), agents=("oracle-pusher", "random-pusher"), limit=1, backend="serial",
                       record="all")
    records = run_suites(config, run, progress=False)
    assert len(records) == 2
    return run, records


def _frames(path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def test_replay_picks_the_episode_of_the_agent_and_writes_a_video(run_dir, tmp_path, capsys):
    run, records = run_dir
    rec = next(r for r in records if r["agent"] == "random-pusher")
    out = tmp_path / "random.mp4"
    assert main(["replay", str(run), rec["episode_id"], "--agent", "random-pusher", "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"replay: {out}"
    assert _frames(out) == rec["metrics"]["steps"] + 1


def test_replay_of_an_episode_two_agents_recorded_lists_them(run_dir, capsys):
    run, records = run_dir
    assert main(["replay", str(run), records[0]["episode_id"]]) == 2
    err = capsys.readouterr().err
    assert f"episode '{records[0]['episode_id']}' matches 2 recordings; pick one with --suite, --agent or --seed" in err
    assert "agent oracle-pusher" in err and "agent random-pusher" in err


def test_replay_of_an_unknown_episode_names_the_nearest(run_dir, capsys):
    run, records = run_dir
    episode = records[0]["episode_id"]
    assert main(["replay", str(run), episode[:-1] + "9"]) == 2
    err = capsys.readouterr().err
    assert f"unknown episode '{episode[:-1]}9'; did you mean '{episode}'" in err
    assert main(["replay", str(run), episode, "--agent", "map-pusher"]) == 2
    assert "has no recording with agent 'map-pusher'" in capsys.readouterr().err


def test_replay_says_why_an_episode_that_ran_was_not_recorded(run_dir, tmp_path, capsys):
    run, records = run_dir
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    doc = json.loads((copy / "run.json").read_text())
    doc["config"]["record"] = "failures"
    (copy / "run.json").write_text(json.dumps(doc))
    oracle = next(r for r in records if r["agent"] == "oracle-pusher")
    (copy / REPLAYS_DIR / f"{replay_stem(oracle)}.npz").unlink()
    assert main(["replay", str(copy), oracle["episode_id"], "--agent", "oracle-pusher"]) == 2
    err = capsys.readouterr().err
    assert "ran (1 record, 1 successful)" in err and "the run used --record failures" in err and "--record all" in err


def test_replay_of_a_recording_path_and_of_a_bad_file(run_dir, tmp_path, capsys):
    run, records = run_dir
    name = f"{replay_stem(records[0])}.npz"
    out = tmp_path / "x.mp4"
    assert main(["replay", str(run), f"{REPLAYS_DIR}/{name}", "--out", str(out), "--fps", "2"]) == 0
    assert _frames(out) == load_recording(run / REPLAYS_DIR / name).num_frames
    bad = tmp_path / "bad.npz"
    bad.write_text("not a recording")
    assert main(["replay", str(run), str(bad)]) == 2
    assert f"cfharness replay: {bad}: not an episode recording" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "no-run"), "ep"]) == 2
    assert "run folder not found" in capsys.readouterr().err


def test_run_refuses_a_bad_record_mode_before_writing_anything(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", "--suite", "regression-rearrange", "--record", "failure", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--record: expected one of failures, all, none, got 'failure'; did you mean 'failures'?" in err
    assert not out.exists()


def test_report_renders_the_missing_videos_and_replaces_mp4v_ones(run_dir, tmp_path):
    run, records = run_dir
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    for video in (copy / REPLAYS_DIR).glob("*.mp4"):
        video.unlink()
    old = copy / REPLAYS_DIR / f"{replay_stem(records[0])}.mp4"  # what an older harness wrote: browsers show it black
    writer = cv2.VideoWriter(str(old), cv2.VideoWriter_fourcc(*"mp4v"), 1.0, (64, 48))
    for _ in range(2):
        writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    assert video_codec(old) == "mpeg4"
    assert main(["report", str(copy)]) == 0
    for rec in records:
        video = copy / REPLAYS_DIR / f"{replay_stem(rec)}.mp4"
        assert _frames(video) == rec["metrics"]["steps"] + 1 and video_codec(video) == "h264"
