"""Episode recordings: what a run records (all; failures with one success per suite and agent),
that recording leaves the episode's results as they were, the file format round trip and its
errors, and the videos: H.264 MP4 one frame per step, the goal on the first frame, what each
frame says, the GIF fallback without PyAV, old mp4v videos replaced."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from agents.pusher import parse_push_instruction
from conceptfusion.errors import HarnessError, MissingFileError, ReplayFormatError
from harness.replay import record as record_module
from harness.replay import video as video_module
from harness.replay.captions import FrameText
from harness.replay.draw import FRAME_SHAPE, Renderer, draw_frame
from harness.replay.record import (
    FORMAT_VERSION, EpisodeRecorder, Recording, load_recording, read_header, save_recording, success_marker,
)
from harness.replay.video import HOLD_LAST_S, render_missing_videos, render_video, video_codec, video_path
from harness.report.paths import MAP_SUFFIX, REPLAYS_DIR, replay_stem
from harness.runner.run import RunConfig, episode_jobs, run_suites
from harness.runner.suites import get_suite
from sim_envs.scenes.episodes import load_episodes


def _outcome(rec: dict) -> tuple:
    return rec["suite"], rec["agent"], rec["episode_id"], rec["seed"], rec["status"], json.dumps(rec["metrics"], sort_keys=True)


def _recording_path(run: Path, rec: dict) -> Path:
    return run / REPLAYS_DIR / f"{replay_stem(rec)}.npz"


@pytest.fixture(scope="module")
def rearrange_run(tmp_path_factory):
    """One tabletop episode each for the map pusher (oracle perception) and the random pusher, all
    recorded (with room for the final map, whatever its size)."""
    run = tmp_path_factory.mktemp("rearrange")
    config = RunConfig(suites=("regression-rearrange",), agents=("map-pusher", "random-pusher"), limit=1, backend="serial",
                       record="all")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(record_module, "MAP_BUDGET_BYTES", 2**40)
        return run, run_suites(config, run, progress=False)


@pytest.fixture(scope="module")
def search_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("search")
    config = RunConfig(suites=("regression-search",), agents=("random-walker",), limit=1, backend="serial", record="all")
    return run, run_suites(config, run, progress=False)


def test_record_all_writes_every_episode_with_its_steps(rearrange_run):
    run, records = rearrange_run
    assert json.loads((run / "run.json").read_text())["config"]["record"] == "all"
    for rec in records:
        r = load_recording(_recording_path(run, rec))
        steps = rec["metrics"]["steps"]
        assert r.num_frames == steps + 1 and r.arrays["actions_ta"].shape == (steps, 5)
        assert (r.header["episode_id"], r.header["agent"], r.header["seed"]) == (rec["episode_id"], rec["agent"], rec["seed"])
        assert r.header["success"] == rec["metrics"]["success"] and r.header["status"] == rec["status"]
        assert r.arrays["objects_tn2"].shape[:2] == (steps + 1, len(r.header["objects"]["ids"]))
        assert r.frame_rgb(0).shape == (96, 128, 3)  # the suite's observation size
        assert r.arrays["success_t"][-1] == rec["metrics"]["success"]
        assert r.arrays["table_xy_22"].shape == (2, 2) and r.arrays["line_22"].shape == (2, 2)


def test_the_map_agents_answers_and_final_map_are_recorded(rearrange_run):
    from conceptfusion.map.persistence import load_map

    run, records = rearrange_run
    rec = next(r for r in records if r["agent"] == "map-pusher")
    r = load_recording(_recording_path(run, rec))
    names = [name for name, _ in parse_push_instruction(r.header["goal"])]
    assert set(r.queries) <= set(names) and r.queries, (r.queries, names)
    found = r.arrays["answer_found_tq"]
    assert found.shape == (r.num_frames, len(r.queries)) and found[0, 0] == 1  # asked and found on the first frame
    med, box = r.arrays["answer_median_tq3"][0, 0], r.arrays["answer_box_tq23"][0, 0]
    assert np.all(box[0] <= med) and np.all(med <= box[1])
    table = r.arrays["table_xy_22"]
    assert np.all(med[:2] >= table[0]) and np.all(med[:2] <= table[1])  # the object is on the table
    map_file = run / REPLAYS_DIR / r.header["map"]["file"]
    assert map_file.name == replay_stem(rec) + MAP_SUFFIX
    assert len(load_map(map_file).points) == r.header["map"]["points"] > 0
    plain = load_recording(_recording_path(run, next(x for x in records if x["agent"] == "random-pusher")))
    assert plain.queries == [] and "skipped" in plain.header["map"]


def test_recording_leaves_the_episode_results_unchanged(rearrange_run):
    run, records = rearrange_run
    rec = next(r for r in records if r["agent"] == "map-pusher")
    config = RunConfig(suites=("regression-rearrange",), agents=("map-pusher",), limit=1, backend="serial", record="none")
    (job,) = episode_jobs(get_suite("regression-rearrange"), config, "plain")
    assert job.record == "none" and job.out_dir is None
    (plain,) = job.run()
    assert _outcome(plain) == _outcome(rec)
    assert "record_s" in rec["timings"] and "record_s" not in plain["timings"]


def test_a_search_recording_holds_the_path_floor_plan_and_goal(search_run):
    run, (rec,) = search_run
    r = load_recording(_recording_path(run, rec))
    pose = r.arrays["pose_t3"]
    assert pose.shape == (rec["metrics"]["steps"] + 1, 3)
    np.testing.assert_allclose(pose[:, :2], rec["extras"]["path_xy"], atol=1e-3)
    episode = load_episodes(get_suite("regression-search").episodes_file).episodes[0]
    np.testing.assert_allclose(pose[0], episode.start_pose, atol=1e-9)
    box = r.arrays["goal_box_23"]
    np.testing.assert_allclose((box[0, :2] + box[1, :2]) / 2, rec["extras"]["goal_xy"], atol=1e-3)
    blocked, floor = r.arrays["floor_blocked_hw"], r.header["floor"]
    cell = np.floor((pose[:, :2] - floor["origin"]) / floor["cell"]).astype(int)
    assert not blocked[cell[:, 1], cell[:, 0]].any()  # the base never stands in a wall
    assert blocked.any() and r.header["goal"] == episode.instruction and r.header["map_answers"] is False


def test_record_failures_keeps_every_failure_and_one_success_per_suite_and_agent(tmp_path):
    config = RunConfig(suites=("regression-rearrange",), agents=("oracle-pusher", "random-pusher"), limit=3, backend="serial")
    assert config.record == "failures"
    records = run_suites(config, tmp_path, progress=False)
    wins = [r for r in records if r["metrics"]["success"]]
    assert len(wins) >= 2 and any(not r["metrics"]["success"] for r in records), "the test needs 2 successes and a failure"
    assert {r["agent"] for r in wins} == {"oracle-pusher"}
    kept = [r for r in records if _recording_path(tmp_path, r).is_file()]
    failed = [r for r in records if not r["metrics"]["success"]]
    (example,) = [r for r in kept if r["metrics"]["success"]]  # one success of the oracle, not one per episode
    assert sorted(map(replay_stem, kept)) == sorted(map(replay_stem, failed + [example]))
    assert read_header(_recording_path(tmp_path, example))["recorded_as"] == "example success"
    assert {read_header(_recording_path(tmp_path, r))["recorded_as"] for r in failed} == {"failure"}
    marker = success_marker(tmp_path / REPLAYS_DIR, {"suite": "regression-rearrange", "agent": "oracle-pusher"})
    assert json.loads(marker.read_text())["recording"] == f"{replay_stem(example)}.npz"
    listed = sorted(p.name for p in (tmp_path / REPLAYS_DIR).iterdir() if not p.name.startswith("."))
    assert listed == sorted(f"{replay_stem(r)}{s}" for r in kept for s in (".npz", ".mp4"))  # videos made in the worker


def test_an_example_success_already_in_the_folder_is_not_recorded_again(tmp_path):
    def recorder(name, agent="a"):
        rec = EpisodeRecorder("some_task", {"suite": "s", "agent": agent, "episode_id": name, "seed": 0}, tmp_path / f"{name}.npz")
        rec.begin(None, {"rgb": np.zeros((4, 4, 3), np.uint8)}, {})
        return rec

    assert recorder("first").mode == "failures"
    assert [p.name for p in recorder("first").finish(status="ok", metrics={"success": True})] == ["first.npz"]
    assert recorder("second").finish(status="ok", metrics={"success": True}) == []  # another worker's, later
    assert [p.name for p in recorder("other", agent="b").finish(status="ok", metrics={"success": True})] == ["other.npz"]
    assert [p.name for p in recorder("lost").finish(status="ok", metrics={"success": False})] == ["lost.npz"]
    assert read_header(tmp_path / "first.npz")["recorded_as"] == "example success"
    assert read_header(tmp_path / "lost.npz")["recorded_as"] == "failure"


def test_record_none_writes_nothing_and_a_bad_mode_names_the_flag(tmp_path):
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial", record="none")
    run_suites(config, tmp_path, progress=False)
    assert not (tmp_path / REPLAYS_DIR).exists()
    with pytest.raises(HarnessError, match=r"--record: expected one of failures, all, none, got 'faliures'; did you mean 'failures'"):
        RunConfig(suites=("regression-rearrange",), record="faliures")
    with pytest.raises(HarnessError, match=r"--record: expected one of failures, all, none, got True"):
        RunConfig(suites=("regression-rearrange",), record=True)


def test_a_run_json_without_the_record_setting_still_resumes(tmp_path):
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial", record="none")
    first = run_suites(config, tmp_path, progress=False)
    doc = json.loads((tmp_path / "run.json").read_text())
    del doc["config"]["record"]
    (tmp_path / "run.json").write_text(json.dumps(doc))
    resumed = run_suites(config, tmp_path, resume=True, progress=False)
    assert [_outcome(r) for r in resumed] == [_outcome(r) for r in first]


def test_round_trip_of_a_recording(rearrange_run, tmp_path):
    run, records = rearrange_run
    src = _recording_path(run, records[0])
    r = load_recording(src)
    copy = save_recording(r, tmp_path / "copy.npz")
    r2 = load_recording(copy)
    assert r2.header == r.header and r.header["format"] == "cfharness-replay" and r.header["version"] == FORMAT_VERSION
    assert sorted(r2.arrays) == sorted(r.arrays)
    for name in r.arrays:
        np.testing.assert_array_equal(r2.arrays[name], r.arrays[name], err_msg=name)
    assert read_header(copy)["episode_id"] == records[0]["episode_id"]


def _tiny_recording() -> Recording:
    """Two frames, one step, one query answered on the first frame; built by hand."""
    class Mapper:
        answers: dict = {}

    class Agent:
        mapper = Mapper()

    class Region:
        points_n3 = np.array([[0.0, 0.0, 0.0], [0.2, 0.4, 0.1], [0.1, 0.1, 0.05]])

    class Answer:
        found, best, reason = True, Region(), ""

    rec = EpisodeRecorder("some_task", {"suite": "s", "agent": "a", "episode_id": "e", "seed": 0}, "unused.npz",
                          mode="all", agent=Agent())
    rgb = np.zeros((12, 16, 3), np.uint8)
    rgb[:, :8] = (255, 0, 0)
    rec.begin(None, {"rgb": rgb}, {})
    Agent.mapper.answers = {"red cup": Answer()}
    rec.act(np.array([1.0, 2.0], np.float32))
    rec.step({"rgb": rgb}, 1.0, {"success": True})
    assert rec.broken is None
    return rec.recording({"status": "ok", "success": True})


def test_the_final_map_is_saved_only_under_the_budget(tmp_path, monkeypatch):
    from conceptfusion.map.fusion import PointFusionMap
    from conceptfusion.map.persistence import load_map

    class Config:
        persistent = True

    the_map = PointFusionMap(4)
    feats = np.zeros((8, 8, 4), np.float32)
    feats[..., 0] = 1.0
    the_map.integrate(np.full((8, 8, 3), 128, np.uint8), np.ones((8, 8)), [[8, 0, 4], [0, 8, 4], [0, 0, 1]], np.eye(4), feats)

    class Mapper:
        config, map, answers = Config(), the_map, {}

    class Agent:
        mapper = Mapper()

    def recorder(name):
        rec = EpisodeRecorder("some_task", {"suite": "s", "agent": "a", "episode_id": name, "seed": 0}, tmp_path / f"{name}.npz",
                              mode="failures", agent=Agent())
        rec.begin(None, {"rgb": np.zeros((4, 4, 3), np.uint8)}, {})
        return rec

    recorder("ok").finish(status="ok", metrics={"success": True})  # the example success of suite s, agent a
    assert recorder("ok2").finish(status="ok", metrics={"success": True}) == []  # a second success: nothing written
    monkeypatch.setattr(record_module, "MAP_BUDGET_BYTES", 0)
    (only,) = recorder("over").finish(status="ok", metrics={"success": False})
    assert only.name == "over.npz" and "does not fit the 0 MB budget" in read_header(only)["map"]["skipped"]
    # a budget of a few points: the map is thinned on a voxel grid to fit, each kept point exact
    monkeypatch.setattr(record_module, "MAP_BUDGET_BYTES", the_map.nbytes() - 1)
    written = recorder("thin").finish(status="ok", metrics={"success": False})
    header = read_header(tmp_path / "thin.npz")["map"]
    thinned = load_map(tmp_path / "thin.map.npz")
    assert header["thinned_from"] == len(the_map) > header["points"] == len(thinned) > 0 and header["voxel_m"] > 0
    assert thinned.nbytes() <= record_module.MAP_BUDGET_BYTES and len(written) == 2
    monkeypatch.setattr(record_module, "MAP_BUDGET_BYTES", 2**30)
    written = recorder("under").finish(status="failed", metrics={"success": False}, error="boom")
    assert [p.name for p in written] == ["under.map.npz", "under.npz"]
    header = read_header(tmp_path / "under.npz")
    assert header["map"]["file"] == "under.map.npz" and header["error"] == "boom" and header["status"] == "failed"
    assert len(load_map(tmp_path / "under.map.npz").points) == header["map"]["points"] == len(the_map.points) > 0


def test_the_recorder_by_hand():
    r = _tiny_recording()
    assert r.num_frames == 2 and r.queries == ["red cup"]
    np.testing.assert_array_equal(r.arrays["actions_ta"], [[1.0, 2.0]])
    np.testing.assert_array_equal(r.arrays["answer_found_tq"], [[1], [1]])  # the last frame keeps the last answer
    np.testing.assert_allclose(r.arrays["answer_median_tq3"][0, 0], [0.1, 0.1, 0.05])
    np.testing.assert_allclose(r.arrays["answer_box_tq23"][1, 0], [[0, 0, 0], [0.2, 0.4, 0.1]])
    np.testing.assert_array_equal(r.arrays["reward_t"], [0.0, 1.0])
    np.testing.assert_array_equal(r.arrays["success_t"], [False, True])
    px = r.frame_rgb(1)
    assert px.shape == (12, 16, 3) and px[6, 2, 0] > 200 and px[6, 13, 0] < 60  # red left half survives JPEG


@pytest.mark.parametrize("damage, match", [
    ("truncate", r"truncated or corrupt"),
    ("text", r"expected an \.npz archive \(zip\), the file starts with b'hell'"),
    ("map", r"not an episode recording: expected format 'cfharness-replay', got 'conceptfusion-map'"),
    ("newer", r"format version 99 is newer than this harness reads \(1\)"),
    ("no_frames", r"the recording lacks arrays frames_jpeg"),
    ("short_rewards", r"array 'reward_t': expected one row per frame \(2\), got 1"),
])
def test_a_bad_recording_file_is_a_clear_error(tmp_path, damage, match):
    path = save_recording(_tiny_recording(), tmp_path / "r.npz")
    if damage == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif damage == "text":
        path.write_text("hello, not a recording")
    elif damage == "map":
        from conceptfusion.map.fusion import PointFusionMap
        from conceptfusion.map.persistence import save_map

        save_map(PointFusionMap(4), path)
    else:
        r = _tiny_recording()
        arrays = dict(r.arrays)
        header = dict(r.header)
        if damage == "newer":
            header["version"] = 99
            buf_header = json.dumps({**header, "format": "cfharness-replay"}).encode()
            np.savez(path, header=np.frombuffer(buf_header, np.uint8), **arrays)
        else:
            if damage == "no_frames":
                del arrays["frames_jpeg"]
            else:
                arrays["reward_t"] = arrays["reward_t"][:1]
            save_recording(Recording(header, arrays), path)
    with pytest.raises(ReplayFormatError, match=match) as info:
        load_recording(path)
    assert str(path) in str(info.value)


def test_a_missing_recording_is_a_missing_file_error(tmp_path):
    with pytest.raises(MissingFileError, match="recording not found"):
        load_recording(tmp_path / "nothing.npz")
    with pytest.raises(ReplayFormatError, match="got a folder"):
        load_recording(tmp_path)


def _decode(path) -> tuple[list[np.ndarray], dict]:
    """Every frame of a video (RGB) and its stream facts, through PyAV."""
    av = pytest.importorskip("av")
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        facts = {"codec": stream.codec_context.name, "pix_fmt": stream.codec_context.pix_fmt,
                 "seconds": container.duration / 1e6}
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    return frames, facts


def test_a_video_is_h264_with_one_frame_per_step_and_the_goal_on_its_first_frame(search_run, tmp_path):
    run, (rec,) = search_run
    r = load_recording(_recording_path(run, rec))
    video = render_video(r, tmp_path / "search.mp4")
    frames, facts = _decode(video)
    assert video.suffix == ".mp4" and facts["codec"] == "h264" == video_codec(video) and facts["pix_fmt"] == "yuv420p"
    assert len(frames) == r.num_frames and frames[0].shape == FRAME_SHAPE and FRAME_SHAPE[0] % 2 == FRAME_SHAPE[1] % 2 == 0
    steps = r.num_frames - 1  # the last frame stays on screen HOLD_LAST_S instead of one frame time (4 fps)
    assert facts["seconds"] == pytest.approx(steps / 4 + HOLD_LAST_S, abs=0.05)
    data = video.read_bytes()
    assert 0 < data.find(b"moov") < data.find(b"mdat")  # faststart: the index first, so it plays while loading
    assert cv2.VideoCapture(str(video)).read()[0]  # OpenCV reads it too
    first = draw_frame(r, 0)
    assert first.shape == FRAME_SHAPE
    # the video's first frame matches the drawn one up to compression
    assert np.abs(frames[0].astype(int) - first.astype(int)).mean() < 6
    # its banner holds the goal: white text on the blue banner, starting at the left
    banner = frames[0][:44].astype(int)
    background = np.median(banner.reshape(-1, 3), axis=0)
    text = np.abs(banner - background).sum(axis=2) > 150
    assert r.header["goal"] and text.any(axis=0)[8:60].any() and text.mean() > 0.03
    blank = r.header.copy()
    blank["goal"] = blank["instruction"] = ""
    other = Renderer(Recording(blank, r.arrays)).frame(0)[:44]
    assert np.abs(other.astype(int)[:, :, ::-1] - frames[0][:44]).mean() > 5  # another goal: another banner


def test_each_frame_says_the_goal_the_distance_to_success_and_the_maps_answer(search_run):
    run, (rec,) = search_run
    r = load_recording(_recording_path(run, rec))
    text = FrameText(r)
    pose, box = r.arrays["pose_t3"], r.arrays["goal_box_23"]
    # worked out here: the base's horizontal distance to the goal object's footprint at the start
    gap = np.maximum(np.maximum(box[0, :2] - pose[0, :2], 0), pose[0, :2] - box[1, :2])
    first = text.lines(0)
    assert first[0] == f"Goal: {r.header['goal']}"
    assert f"{np.linalg.norm(gap):.2f} m to goal (success within 1.00 m)" in first
    assert "map: the agent keeps none" in first  # a random walker has no map
    last = text.lines(r.num_frames - 1)
    assert last[-1].startswith("SUCCESS" if rec["metrics"]["success"] else "FAILED")
    assert f"{rec['metrics']['distance_to_goal']:.2f} m to goal (success within 1.00 m)" in last[2]
    # a recording of an older harness (no per-frame distance or goal box): worked out from the pose
    older = Recording(r.header, {k: v for k, v in r.arrays.items() if k not in ("goal_distance_t", "goal_box_t23")})
    assert FrameText(older).lines(0) == first
    # a chain reveals its next goal: the banner follows from that frame on
    chain = Recording({**r.header, "goal_changes": [[3, "the sofa"]]}, r.arrays)
    assert [FrameText(chain).goal(t) for t in (2, 3, 4)] == [f"Goal: {r.header['goal']}", "Goal: the sofa", "Goal: the sofa"]


def test_the_last_frame_says_why_the_episode_stopped(tmp_path):
    class Agent:
        mapper = type("Mapper", (), {"answers": {}})()

    class NotFound:
        found, best, reason = False, None, "no region scored above the floor"

    rec = EpisodeRecorder("some_task", {"suite": "s", "agent": "a", "episode_id": "e", "seed": 0, "instruction": "the red cup"},
                          tmp_path / "e.npz", agent=Agent())
    rec.begin(None, {"rgb": np.zeros((12, 16, 3), np.uint8)}, {})
    Agent.mapper.answers = {"red cup": NotFound()}
    rec.act(np.zeros(3, np.float32))
    rec.step({"rgb": np.zeros((12, 16, 3), np.uint8)}, 0.0, {})
    (path,) = rec.finish(status="ok", metrics={"success": False},
                         extras={"stop_reason": "not_found", "goal": "the red cup", "path_xy": [[0, 0]]})
    r = load_recording(path)
    assert r.header["stop_reason"] == "not_found" and "path_xy" not in r.header  # only the outcome's extras
    lines = FrameText(r).lines(1)
    assert lines[0] == "Goal: the red cup"
    assert "map: 'red cup' not found (no region scored above the floor)" in lines
    assert lines[-1] == "FAILED: stop reason 'not_found'"
    assert not any(line.startswith("FAILED") for line in FrameText(r).lines(0))  # the outcome on the last frame only


def test_a_rearrangement_frame_says_how_far_each_target_is_past_the_line(rearrange_run):
    run, records = rearrange_run
    for rec in records:
        r = load_recording(_recording_path(run, rec))
        past = r.arrays["target_past_line_tk"]
        names, targets = r.header["objects"]["names"], r.header["objects"]["targets"]
        assert past.shape == (r.num_frames, len(targets)) and np.all(np.isfinite(past))
        assert (bool(np.all(past[-1] >= 0.02)) and r.arrays["distractor_shift_t"][-1] < 0.05) == rec["metrics"]["success"]
        lines = FrameText(r).lines(r.num_frames - 1)
        for k, target in enumerate(targets):
            d = past[-1, k]
            where = f"{100 * d:.1f} cm past the line" if d >= 0 else f"{100 * -d:.1f} cm on the wrong side of the line"
            assert f"{names[target]}: {where}" in " | ".join(lines)


def test_the_video_falls_back_to_a_gif_without_pyav(rearrange_run, tmp_path, monkeypatch, caplog):
    Image = pytest.importorskip("PIL.Image")
    run, records = rearrange_run
    r = load_recording(_recording_path(run, records[0]))
    monkeypatch.setitem(__import__("sys").modules, "av", None)  # import av raises ImportError
    monkeypatch.setattr(video_module, "_warned_gif", False)
    with caplog.at_level(logging.WARNING):
        video = render_video(r, tmp_path / "push.mp4")
    assert video == tmp_path / "push.gif" and not (tmp_path / "push.mp4").exists()
    assert "replay videos are GIFs, not MP4" in caplog.text and "pip install av" in caplog.text
    with Image.open(video) as gif:
        assert gif.n_frames == r.num_frames


def test_render_missing_videos_renders_each_recording_once_and_skips_bad_files(rearrange_run, tmp_path, caplog):
    run, records = rearrange_run
    folder = tmp_path / REPLAYS_DIR
    folder.mkdir()
    for rec in records:
        src = _recording_path(run, rec)
        (folder / src.name).write_bytes(src.read_bytes())
    (folder / "broken.npz").write_bytes(b"PK\x03\x04 not really")
    (folder / f"x{MAP_SUFFIX}").write_bytes(b"a map is no recording")
    with caplog.at_level(logging.WARNING):
        written = render_missing_videos(tmp_path)
    assert sorted(p.name for p in written) == sorted(f"{replay_stem(r)}.mp4" for r in records)
    assert "broken.npz" in caplog.text and "x.map" not in caplog.text
    assert all(video_path(folder / f"{replay_stem(r)}.npz") is not None for r in records)
    assert render_missing_videos(tmp_path) == []  # nothing left to render


def test_render_missing_videos_replaces_an_mp4v_video(rearrange_run, tmp_path):
    run, records = rearrange_run
    folder = tmp_path / REPLAYS_DIR
    folder.mkdir()
    src = _recording_path(run, records[0])
    (folder / src.name).write_bytes(src.read_bytes())
    old = folder / f"{replay_stem(records[0])}.mp4"
    writer = cv2.VideoWriter(str(old), cv2.VideoWriter_fourcc(*"mp4v"), 1.0, (64, 48))  # what older harnesses wrote
    assert writer.isOpened(), "this OpenCV cannot write mp4v"
    for _ in range(3):
        writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    assert video_codec(old) == "mpeg4"
    assert render_missing_videos(tmp_path) == [old]
    frames, facts = _decode(old)
    assert facts["codec"] == "h264" and len(frames) == load_recording(src).num_frames
    assert render_missing_videos(tmp_path) == []


def test_frames_show_the_planner_call_of_their_step():
    """An instruction agent's planner calls (the record's ``extras["planner"]``, copied into the
    recording's header) caption the frames from the step of each call; a failure reads as bad."""
    from types import SimpleNamespace

    from harness.replay.captions import FrameText
    from harness.replay.record import OUTCOME_EXTRAS

    assert "planner" in OUTCOME_EXTRAS
    calls = [{"step": 0, "goals": [], "reasoning": "the map holds 3 objects\nnothing in the map fits yet: explore"},
             {"step": 9, "goals": ["fork (in the kitchen)"], "reasoning": "12 of them in the kitchen\nfitting: fork\ngo to fork"},
             {"step": 20, "goals": [], "reasoning": "", "failure": "server timed out"}]
    text = SimpleNamespace(rec=SimpleNamespace(header={"planner": {"kept_calls": calls}}))
    assert FrameText._planner(text, 5) == ("planner (step 0): nothing fits yet, explore - the map holds 3 objects", "answer")
    assert FrameText._planner(text, 9) == ("planner (step 9): fork (in the kitchen) - fitting: fork", "answer")
    assert FrameText._planner(text, 25) == ("planner failed: server timed out", "bad")
    assert FrameText._planner(SimpleNamespace(rec=SimpleNamespace(header={})), 3) is None
