"""Episode replays: recordings of what an agent saw, did and was told by its map, and videos of them.

* :mod:`harness.replay.record` - :class:`~harness.replay.record.EpisodeRecorder` (follows an
  episode, buffers it, writes ``RUN/replays/<stem>.npz``), the recording format and its reader;
* :mod:`harness.replay.draw` - one video frame: the goal, the camera beside a top-down view with
  the path, the goal and the map's answers, the frame's text, a legend;
* :mod:`harness.replay.captions` - what a frame says: the goal, the distance to success, the
  map's answer, the outcome and why the episode stopped;
* :mod:`harness.replay.video` - a recording to an H.264 MP4 that plays in any browser (PyAV; GIF
  without it); videos for a run's recordings, replacing ones browsers cannot play;
* :mod:`harness.replay.find` - an episode's recording in a run folder (``cfharness replay``).

May import: conceptfusion, sim_envs (floor plans, rearrangement scoring constants), harness.report.paths, harness.runner.results.
"""
