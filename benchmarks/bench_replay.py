"""What recording episodes costs: episode time with ``--record none`` vs ``--record all``, file sizes.

    MUJOCO_GL=egl python benchmarks/bench_replay.py [--limit 3] [--encoder oracle]

Runs the first ``--limit`` episodes of the ``search`` and ``rearrange`` suites for the map agents
(and one map-free agent each), every episode twice in this process, alternately without and
with recording (after one warm-up episode that loads models and builds scenes). Reports per
agent the mean episode time both ways, the overhead in percent (target: at most 10%), the time
the recorder itself spent (``timings.record_s``: buffering and writing, the part that does not
depend on the machine's noise), the recording size (per episode and per frame), the final map
file size when one is written, and the time to render each recording to a video (done later,
by ``cfharness replay`` or ``cfharness report``, not during the episode).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from harness.replay.record import read_header
from harness.replay.video import render_video
from harness.report.paths import MAP_SUFFIX, REPLAYS_DIR, replay_stem
from harness.runner.run import RunConfig, episode_jobs
from harness.runner.suites import get_suite
from harness.runner.tasks import close_cached_envs

CASES = (("search", "map-navigator"), ("search", "random-walker"), ("rearrange", "map-pusher"), ("rearrange", "random-pusher"))


def _jobs(suite: str, agent: str, encoder: str, limit: int, record: str, out: Path):
    config = RunConfig(suites=(suite,), agents=(agent,), encoder=encoder, limit=limit, backend="serial", record=record)
    return episode_jobs(get_suite(suite), config, "bench", out_dir=out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=3, help="episodes per suite (default 3)")
    ap.add_argument("--encoder", default="oracle", help="perception of the map agents (default: oracle, quick)")
    args = ap.parse_args()
    print(f"{'suite':<10} {'agent':<14} {'n':>2} {'none s':>7} {'all s':>7} {'overhead':>8} {'record_s':>8} {'rec %':>6} "
          f"{'rec KB':>7} {'KB/frame':>8} {'map MB':>7} {'video s':>7}")
    totals = {"none": 0.0, "all": 0.0, "record": 0.0}
    with tempfile.TemporaryDirectory() as tmp:
        for suite, agent in CASES:
            out = Path(tmp) / f"{suite}-{agent}"
            plain = _jobs(suite, agent, args.encoder, args.limit, "none", out)
            recorded = _jobs(suite, agent, args.encoder, args.limit, "all", out)
            plain[0].run()  # warm-up: models, scenes, GL context
            t_none, t_all, t_rec, sizes, maps, frames, videos = [], [], [], [], [], [], []
            for a, b in zip(plain, recorded):
                (ra,) = a.run()
                (rb,) = b.run()
                assert ra["metrics"] == rb["metrics"], (ra["metrics"], rb["metrics"])  # recording changes nothing
                t_none.append(ra["timings"]["wall_s"])
                t_all.append(rb["timings"]["wall_s"])
                t_rec.append(rb["timings"]["record_s"])
                path = out / REPLAYS_DIR / f"{replay_stem(rb)}.npz"
                sizes.append(path.stat().st_size)
                frames.append(rb["metrics"]["steps"] + 1)
                m = read_header(path).get("map", {})
                if "file" in m:
                    maps.append((out / REPLAYS_DIR / m["file"]).stat().st_size)
                t0 = time.perf_counter()
                render_video(path)
                videos.append(time.perf_counter() - t0)
            close_cached_envs()
            mn, ma, mr = statistics.mean(t_none), statistics.mean(t_all), statistics.mean(t_rec)
            totals["none"] += sum(t_none)
            totals["all"] += sum(t_all)
            totals["record"] += sum(t_rec)
            map_mb = f"{statistics.mean(maps) / 1e6:7.2f}" if maps else f"{'-':>7}"
            print(f"{suite:<10} {agent:<14} {len(t_none):>2} {mn:7.2f} {ma:7.2f} {100 * (ma - mn) / mn:7.1f}% {mr:8.3f} "
                  f"{100 * mr / ma:5.1f}% {statistics.mean(sizes) / 1e3:7.0f} {sum(sizes) / sum(frames) / 1e3:8.2f} {map_mb} "
                  f"{statistics.mean(videos):7.2f}")
    print(f"\nall episodes: {totals['none']:.1f} s without recording, {totals['all']:.1f} s with "
          f"({100 * (totals['all'] - totals['none']) / totals['none']:+.1f}%); the recorder's own time is "
          f"{100 * totals['record'] / totals['all']:.1f}% of the recorded episodes' time (target <= 10%)")
    print(f"(final maps are saved beside recordings as <stem>{MAP_SUFFIX} when under the budget; see harness.replay.record)")


if __name__ == "__main__":
    main()
