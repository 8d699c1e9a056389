"""Episode replays: recordings of what an agent saw, did and was told by its map, and videos of them.

* :mod:`harness.replay.record` - :class:`~harness.replay.record.EpisodeRecorder` (follows an
  episode, buffers it, writes ``RUN/replays/<stem>.npz``), the recording format and its reader;
* :mod:`harness.replay.video` - a recording to MP4 (GIF fallback): the camera beside a top-down
  view with the path, the goal and the map's answers; videos for a run's recordings;
* :mod:`harness.replay.find` - an episode's recording in a run folder (``cfharness replay``).

May import: conceptfusion, sim_envs (floor plans), harness.report.paths, harness.runner.results.
"""
