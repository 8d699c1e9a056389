"""Turning a recording into a video that plays in any browser.

:func:`render_video` draws each recorded frame (:func:`harness.replay.draw.draw_frame`: the goal,
the camera beside a top-down view, the distance to success, the map's answer, the outcome) and
writes H.264 in an MP4 through PyAV (FFmpeg's libx264): 8-bit 4:2:0 (``yuv420p``) at even width
and height, the ``moov`` atom first (``+faststart``) so a page plays it while it loads, and the
last frame held for :data:`HOLD_LAST_S` so the outcome stays on screen. That is what Chromium,
Firefox and Safari all play. (OpenCV's ``mp4v`` is MPEG-4 Part 2, which browsers do not decode;
OpenCV's wheels cannot write H.264.) Without PyAV (or a PyAV without libx264) the video is a GIF
(Pillow) instead, and the log says why and what to install.

:func:`render_missing_videos` renders every recording of a run folder that has no playable video
yet: none at all, or an MP4 that is not H.264 (an ``mp4v`` one from an older harness), found by
probing its codec (:func:`video_codec`).
"""

from __future__ import annotations

import io
import logging
import math
import os
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from conceptfusion.errors import ConceptFusionError, MissingDependencyError
from conceptfusion.io_utils import atomic_write_bytes
from harness.replay.draw import Renderer
from harness.replay.record import Recording, is_recording_file, load_recording
from harness.report.paths import REPLAYS_DIR, VIDEO_SUFFIXES

__all__ = ["CODEC", "CRF", "HOLD_LAST_S", "render_video", "render_missing_videos", "render_videos_of", "video_path",
           "video_codec", "default_fps"]

_LOG = logging.getLogger(__name__)

CODEC = "h264"
"""The codec of the videos written here (as FFmpeg names it)."""
CRF = 20
"""libx264's constant rate factor: lower is sharper and larger; 20 keeps the overlay's small text
crisp at about 3-6 kB a frame."""
HOLD_LAST_S = 2.0
"""Seconds the last frame (outcome and stop reason) stays on screen before the video ends."""
_PRESET = "veryfast"
_warned_gif = False


def default_fps(recording: Recording) -> float:
    """Frames per second of a recording's video: 4 for search (a step is 0.5 s of driving), 1 for
    tabletop pushes (a step is a whole push)."""
    return 1.0 if recording.task == "tabletop_rearrange" else 4.0


def video_path(recording_path: str | os.PathLike) -> Path | None:
    """The existing video of a recording (``<stem>.mp4`` or ``<stem>.gif`` beside it), or None."""
    p = Path(recording_path)
    for suffix in VIDEO_SUFFIXES:
        v = p.with_suffix(suffix)
        if v.is_file() and v.stat().st_size > 0:
            return v
    return None


def video_codec(path: str | os.PathLike) -> str | None:
    """The codec of the first video stream of the file at ``path`` as FFmpeg names it (``"h264"``,
    ``"mpeg4"`` for OpenCV's ``mp4v``, ``"gif"``), or None when the file is not a readable video.

    Raises:
        MissingDependencyError: PyAV is not installed.
    """
    av = _import_av()
    try:
        with av.open(str(path)) as container:
            streams = container.streams.video
            return str(streams[0].codec_context.name) if streams else None
    except (av.FFmpegError, OSError, ValueError):
        return None


def _import_av():
    try:
        import av
    except ImportError as exc:
        raise MissingDependencyError("an H.264 replay video needs PyAV (FFmpeg with libx264): pip install av") from exc
    return av


def _h264_encoder(av) -> None:
    """Raise MissingDependencyError when this PyAV has no libx264 encoder (a build against a
    system FFmpeg without it); PyPI's wheels carry it."""
    try:
        av.codec.Codec("libx264", "w")
    except ValueError as exc:  # av's UnknownCodecError is a ValueError
        raise MissingDependencyError("this PyAV has no libx264 encoder, so it cannot write H.264; "
                                     "pip install --force-reinstall av (PyPI's wheels carry libx264)") from exc


def _write_mp4(frames, path: Path, fps: float, size: tuple[int, int]) -> None:
    """Encode BGR frames of ``size`` (width, height; both even) to H.264 in MP4 at ``path``."""
    av = _import_av()
    _h264_encoder(av)
    rate = Fraction(fps).limit_denominator(1000)
    with tempfile.TemporaryDirectory(prefix="cf-video-") as tmp:
        # faststart rewrites the file to move the moov atom first: it needs a real file, so the
        # video is encoded in a scratch folder and then written in place atomically
        scratch = Path(tmp) / "video.mp4"
        with av.open(str(scratch), "w", format="mp4", container_options={"movflags": "+faststart"}) as container:
            stream = container.add_stream("libx264", rate=rate)
            stream.width, stream.height, stream.pix_fmt = size[0], size[1], "yuv420p"
            # one thread: episodes record in one worker per core, which libx264's own threads would crowd
            stream.options = {"crf": str(CRF), "preset": _PRESET, "threads": "1"}
            packets = []
            for i, bgr in enumerate(frames):
                frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(bgr), format="bgr24")
                frame.pts = i
                packets += stream.encode(frame)
            packets += stream.encode()  # flush
            if packets:
                # the last frame shows for HOLD_LAST_S: the track ends at the last packet in decode
                # order plus its duration, and with B-frames that packet is not the last one shown
                last, shown_last = packets[-1], max(p.pts for p in packets)
                last.duration = int(round(HOLD_LAST_S / float(last.time_base))) + shown_last - last.pts
            for packet in packets:
                container.mux(packet)
        atomic_write_bytes(path, scratch.read_bytes())


def _write_gif(frames, path: Path, fps: float) -> None:
    try:
        from PIL import Image
    except ImportError as exc:
        raise MissingDependencyError("a GIF replay needs Pillow: pip install pillow") from exc
    images = [Image.fromarray(np.ascontiguousarray(f[:, :, ::-1])) for f in frames]
    durations = [int(round(1000 / fps))] * len(images)
    durations[-1] = max(durations[-1], int(round(1000 * HOLD_LAST_S)))
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0)
    atomic_write_bytes(path, buf.getvalue())


def render_video(recording: Recording | str | os.PathLike, out: str | os.PathLike | None = None, *,
                 fps: float | None = None) -> Path:
    """Render a recording (or the recording file at a path) to a video; returns its path.

    ``out``: the video file, ``.mp4`` or ``.gif`` (default: the recording's path with ``.mp4``;
    needed when ``recording`` is a :class:`Recording`). An ``.mp4`` is H.264 through PyAV (see the
    module docstring); without PyAV or its libx264 it is written as a GIF beside it instead (the
    log says why), and that path is returned. One video frame per recorded frame, at ``fps``
    (default :func:`default_fps`), the last one held for :data:`HOLD_LAST_S`.

    Raises:
        ValueError: ``out`` with another ending, ``fps`` <= 0, or no ``out`` for a Recording.
        ReplayFormatError, MissingFileError: from :func:`~harness.replay.record.load_recording`.
    """
    global _warned_gif
    if isinstance(recording, Recording):
        rec = recording
        if out is None:
            raise ValueError("render_video: expected out= (a .mp4 or .gif path) for a Recording")
    else:
        rec = load_recording(recording)
        if out is None:
            out = Path(recording).with_suffix(".mp4")
    out = Path(out)
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video: expected a file ending in {' or '.join(VIDEO_SUFFIXES)}, got {out.name!r}")
    fps = default_fps(rec) if fps is None else float(fps)
    if not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps: expected a number > 0, got {fps!r}")
    renderer = Renderer(rec)
    first = renderer.frame(0)
    size = (first.shape[1], first.shape[0])
    out.parent.mkdir(parents=True, exist_ok=True)

    def frames():
        yield first
        for t in range(1, rec.num_frames):
            yield renderer.frame(t)

    if out.suffix.lower() == ".mp4":
        try:
            _write_mp4(frames(), out, fps, size)
            return out
        except MissingDependencyError as exc:
            (_LOG.warning if not _warned_gif else _LOG.debug)("replay videos are GIFs, not MP4: %s", exc)
            _warned_gif = True
        out = out.with_suffix(".gif")
    _write_gif(list(frames()), out, fps)
    return out


def _playable(video: Path) -> bool:
    """Whether an existing video plays in browsers: a GIF, or an MP4 holding H.264. Without PyAV
    an MP4 cannot be probed, and no H.264 could replace it anyway: it counts as playable."""
    if video.suffix.lower() != ".mp4":
        return True
    try:
        return video_codec(video) == CODEC
    except MissingDependencyError:
        return True


def render_missing_videos(run_dir: str | os.PathLike) -> list[Path]:
    """Render a video for every recording in ``run_dir/replays/`` that has no playable one yet
    (none, or an MP4 that is not H.264: an ``mp4v`` video of an older harness is replaced);
    returns the videos written. A recording that cannot be read is logged and skipped (the
    report goes on)."""
    folder = Path(run_dir) / REPLAYS_DIR
    if not folder.is_dir():
        return []
    todo = []
    for path in sorted(folder.glob("*.npz")):
        video = video_path(path)
        if video is None or not _playable(video):
            todo.append(path)
    return render_videos_of(todo)


def render_videos_of(paths) -> list[Path]:
    """Render the video of every recording file among ``paths`` (what
    :meth:`~harness.replay.record.EpisodeRecorder.finish` returns); returns the videos written.
    Episode jobs call it in their worker, so that a run's videos are made alongside its episodes
    rather than one after another by the report. A recording that cannot be drawn is logged and
    skipped; the report tries again (:func:`render_missing_videos`)."""
    written = []
    for path in paths:
        path = Path(path)
        if not is_recording_file(path):
            continue
        try:
            written.append(render_video(path))
        except (ConceptFusionError, OSError, ValueError) as exc:
            _LOG.warning("no video for %s: %s", path, exc)
    return written
