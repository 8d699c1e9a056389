"""A replay video of a real episode plays in headless Chromium: from a page on disk (as the HTML
report links it) and from the map viewer's server, which answers the byte ranges a browser asks
for when it seeks. (OpenCV's mp4v videos showed a black 0:00 player here.)"""

from __future__ import annotations

import shutil
import urllib.request

import pytest

from harness.demo.run import run_demo
from harness.demo.scoring import DemoConfig
from harness.replay.video import HOLD_LAST_S, video_codec
from harness.report.paths import REPLAYS_DIR, replay_stem
from harness.runner.run import RunConfig, run_suites
from harness.viewer.server import ViewerServer

_STATE = ("const v = document.querySelector('video'); return {ready: v.readyState, error: v.error && v.error.code, "
          "time: v.currentTime, duration: v.duration, width: v.videoWidth, height: v.videoHeight, paused: v.paused}")


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    """The video of one recorded tabletop episode (random pusher: a few pushes, 1 frame/s)."""
    run = tmp_path_factory.mktemp("video-run")
    config = RunConfig(suites=("regression-rearrange",), agents=("random-pusher",), limit=1, backend="serial", record="all")
    (rec,) = run_suites(config, run, progress=False)
    video = run / REPLAYS_DIR / f"{replay_stem(rec)}.mp4"
    assert video.is_file() and video_codec(video) == "h264"
    return video, rec["metrics"]["steps"]


def _plays(driver, wait_for, what: str) -> dict:
    """Start the page's muted video from script and wait until its time moves on; its state."""
    wait_for(driver, "document.querySelector('video').readyState >= 2 || document.querySelector('video').error",
             what=f"{what}: video loads")
    before = driver.execute_script(_STATE)
    assert before["error"] is None and before["ready"] >= 2, before
    driver.execute_script("const v = document.querySelector('video'); v.muted = true; window.__play = 'pending'; "
                          "v.play().then(() => { window.__play = 'ok'; }, e => { window.__play = String(e); });")
    wait_for(driver, "window.__play !== 'pending'", what=f"{what}: play() settles")
    assert driver.execute_script("return window.__play") == "ok"
    wait_for(driver, f"document.querySelector('video').currentTime > {before['time']} + 0.3",
             what=f"{what}: playback advances")
    after = driver.execute_script(_STATE)
    assert after["error"] is None and not after["paused"]
    return after


@pytest.mark.browser
def test_a_replay_video_plays_from_a_page_on_disk(chromium, wait_for, replay, tmp_path):
    video, steps = replay
    shutil.copy(video, tmp_path / "replay.mp4")
    page = tmp_path / "page.html"
    page.write_text('<!doctype html><meta charset="utf-8"><video src="replay.mp4" muted playsinline preload="auto"></video>')
    chromium.get(page.as_uri())
    state = _plays(chromium, wait_for, "page on disk")
    assert (state["width"], state["height"]) == (640, 408)
    assert state["duration"] == pytest.approx(steps + HOLD_LAST_S, abs=0.1)  # 1 frame/s, the last held


@pytest.fixture(scope="module")
def viewer_with_replay(tmp_path_factory, replay):
    """The viewer serving a small demo map with a replay video beside it (``map.mp4``)."""
    out = tmp_path_factory.mktemp("viewer-video")
    run_demo(DemoConfig(encoder="color", frames=4, width=96, height=72), out)
    shutil.copy(replay[0], out / "map.mp4")
    with ViewerServer(out / "map.npz", encoder="color") as srv:
        yield srv, out / "map.mp4"


def test_the_viewer_serves_a_video_as_mp4_with_byte_ranges(viewer_with_replay):
    srv, video = viewer_with_replay
    data = video.read_bytes()
    with urllib.request.urlopen(srv.url + "files/map.mp4") as whole:
        assert whole.status == 200 and whole.headers["Content-Type"] == "video/mp4"
        assert whole.headers["Accept-Ranges"] == "bytes" and whole.read() == data
    request = urllib.request.Request(srv.url + "files/map.mp4", headers={"Range": "bytes=100-199"})
    with urllib.request.urlopen(request) as part:
        assert part.status == 206 and part.headers["Content-Range"] == f"bytes 100-199/{len(data)}"
        assert part.read() == data[100:200]
    request = urllib.request.Request(srv.url + "files/map.mp4", headers={"Range": "bytes=-10"})
    with urllib.request.urlopen(request) as tail:
        assert tail.status == 206 and tail.read() == data[-10:]
    request = urllib.request.Request(srv.url + "files/map.mp4", headers={"Range": f"bytes={len(data)}-"})
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(request)
    assert info.value.code == 416 and info.value.headers["Content-Range"] == f"bytes */{len(data)}"


@pytest.mark.browser
def test_the_viewers_replay_panel_plays_and_seeks(chromium, wait_for, viewer_with_replay):
    srv, _ = viewer_with_replay
    chromium.get(srv.url)
    wait_for(chromium, "window.cfViewer && (window.cfViewer.ready || window.cfViewer.error)", what="viewer load")
    assert chromium.execute_script("return document.getElementById('replay').hidden") is False
    state = _plays(chromium, wait_for, "viewer's replay panel")
    assert state["width"] == 640
    chromium.execute_script("const v = document.querySelector('video'); v.pause(); window.__seeked = false; "
                            "v.addEventListener('seeked', () => { window.__seeked = true; }, {once: true}); v.currentTime = 1.5;")
    wait_for(chromium, "window.__seeked", what="seek in the viewer's replay")
    assert chromium.execute_script(_STATE)["time"] == pytest.approx(1.5, abs=0.01)
