"""How long writing the reports of a run takes (report.md with its figures, and report.html), and
its peak memory.

    python benchmarks/bench_report.py [RUN] [--repeat 3]

``RUN``: a run folder (``results.jsonl``, and ``replays/`` and ``heatmaps/`` when recorded); the
reports are written into a temporary folder, never into the run. Without ``RUN`` a synthetic run
of the default comparison's size is built first (437 records over the seven default suites with
the default agents and episode counts, each suite's metric names as the harness records them; no
replays, paths or heatmaps, so no floor plans or heatmaps are drawn).

Per repeat, in this process: the time to build the report (statistics, cards, figures;
:func:`harness.report.markdown.build_report`), to render and write ``report.md`` and
``report.html``, and the peak memory Python allocated meanwhile (``tracemalloc``, which slows the
run a little: the times are from the repeats without it). The first repeat pays for the lazy
imports (matplotlib, scipy). Last, the process's peak resident memory. Videos of the recordings
are not rendered here (``cfharness report`` renders the missing ones first). Target: the default
comparison's reports in at most 30 s.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # this checkout, _machine

import numpy as np  # noqa: E402

from harness.report.html import write_html  # noqa: E402
from harness.report.markdown import build_report, write_markdown  # noqa: E402
from harness.runner.results import RESULTS_FILE, append_record, make_record  # noqa: E402

TARGET_S = 30.0

_SPATIAL = ("canFitInside", "howFar", "isBigger", "isContained", "isToTheLeft", "isToTheRight", "onTopOf", "under")
_OPEN_KINDS = ("name", "synonym", "parent", "colour", "material", "function", "seen", "validation", "held_out_instance",
               "held_out_category")


def _map_metrics(suite: str, rng) -> dict:
    """One record's metrics of a map suite, under the names the harness records."""
    r = lambda: float(rng.random())  # noqa: E731
    if suite == "query-open":
        return {**{f"{k}_{m}": r() for k in _OPEN_KINDS for m in ("miou", "acc25", "found_rate")}, "absent_fp_rate": r(),
                "n_absent": 3.0, "n_queries": 20.0, "n_unseen": 4.0, "map_points": 23000.0 + 1000 * r()}
    if suite == "query-v2":
        return {**{f"{k}_{m}": r() for k in ("text", "image", "click")
                   for m in ("miou", "acc15", "acc25", "acc50", "found_rate", "miou_thresh")},
                "absent_fp_rate": r(), "n_objects": 8.0, "n_skipped": 0.0, "map_points": 23000.0}
    if suite == "spatial-v2":
        return {**{f"acc_{c}": r() for c in _SPATIAL}, **{f"n_{c}": 4.0 for c in _SPATIAL}, "accuracy": r(), "accuracy_fresh": r(),
                "accuracy_seen": r(), "accuracy_parsed": r(), "chance_always_yes": 0.4, "chance_random": 0.3, "n_questions": 30.0,
                "notfound_rate": r(), "parse_fail_rate": 0.05, "parse_rate": 0.95}
    return {"coverage": r(), "fmiou": r(), "macc": r(), "map_points": 23000.0, "n_classes": 8.0, "pixel_acc": r()}


def synthetic_run(folder: Path, seed: int = 0) -> Path:
    """A run folder the size of the default comparison (437 records); returns it."""
    rng = np.random.default_rng(seed)
    out = folder / RESULTS_FILE

    def add(suite, agent, i, metrics, encoder="embedded-v2", **extras):
        append_record(out, make_record(run_id="bench", suite=suite, task="t", agent=agent, encoder=encoder,
                                       episode_id=f"{suite}-{i:04d}", seed=0, status="ok", metrics=metrics,
                                       category=("mug", "bowl", "box", "can")[i % 4], timings={"wall_s": float(1 + rng.random())},
                                       extras={"privileged": False, **extras}))

    episodes = (("rearrange-v2", ("map-pusher", "twin-pusher", "frame-pusher", "random-pusher"), (64, 64, 64, 64)),
                ("search-v2", ("map-navigator", "twin-navigator", "frame-searcher", "random-walker"), (16, 16, 8, 16)),
                ("chain-v2", ("map-navigator", "twin-navigator", "random-walker"), (3, 3, 3)))
    for suite, agents, counts in episodes:
        for agent, n in zip(agents, counts):
            extras = {"uses_map": agent.startswith("map-")}
            if agent.startswith("twin-"):
                extras["twin_of"] = agents[0]
            for i in range(n):
                win = bool(rng.random() < (0.1 if agent.startswith("random") else 0.6))
                metrics = {"success": win, "steps": int(50 + 100 * rng.random())}
                if suite != "rearrange-v2":
                    metrics.update(spl=float(win * rng.random()), collisions=0, distance_to_goal=float(3 * rng.random()),
                                   path_length=float(20 * rng.random()), shortest_path_length=5.0)
                if suite == "chain-v2":
                    metrics.update(chain_length=2 + i, goals_reached=int(win), reached_1=win, reached_2=False)
                add(suite, agent, i, metrics, encoder="none" if agent.startswith("random") else "embedded-v2",
                    description_kind=("name", "synonym", "attribute", "function")[i % 4], **extras)
    for suite, agents, n in (("query-open", ("conceptfusion",), 24), ("query-v2", ("conceptfusion",), 12),
                             ("spatial-v2", ("map-3d", "frame-2.5d"), 16), ("ablation-v2", ("full", "global", "local", "no-uniqueness"), 12)):
        for agent in agents:
            for i in range(n):
                add(suite, agent, i, _map_metrics(suite, rng))
    return folder


def _write(run: Path, out: Path) -> tuple[float, float, float]:
    """(build s, Markdown s, HTML s) of one report of ``run`` into ``out``."""
    t0 = time.perf_counter()
    doc = build_report([run], out)
    t1 = time.perf_counter()
    write_markdown(doc)
    t2 = time.perf_counter()
    write_html(doc)
    return t1 - t0, t2 - t1, time.perf_counter() - t2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?", help="a run folder (default: a synthetic one of the default comparison's size)")
    ap.add_argument("--repeat", type=int, default=3, help="reports written, timed (default 3), then one more under tracemalloc")
    args = ap.parse_args()
    try:
        from _machine import probe_line

        print(probe_line())
    except Exception as exc:  # noqa: BLE001 - the probe is optional (threadpoolctl)
        print(f"(machine probe unavailable: {exc})")
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(args.run) if args.run else synthetic_run(Path(tmp) / "run")
        records = sum(1 for line in (run / RESULTS_FILE).open() if line.strip())
        print(f"run: {run if args.run else 'synthetic, default comparison size'} ({records} records)")
        print(f"{'repeat':>6} {'build s':>8} {'md s':>6} {'html s':>7} {'total s':>8}")
        totals = []
        for k in range(args.repeat):
            b, m, h = _write(run, Path(tmp) / f"report-{k}")
            totals.append(b + m + h)
            print(f"{k + 1:>6} {b:8.2f} {m:6.2f} {h:7.2f} {b + m + h:8.2f}" + ("  (imports included)" if k == 0 else ""))
        tracemalloc.start()
        _write(run, Path(tmp) / "report-traced")
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        out = Path(tmp) / "report-0"
        sizes = {name: (out / name).stat().st_size for name in ("report.md", "report.html")}
        figures = len(list(out.glob("*.png")))
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\nreport.md {sizes['report.md'] / 1e3:.0f} kB, report.html {sizes['report.html'] / 1e6:.2f} MB, {figures} figures")
    print(f"peak Python allocations while writing one report: {peak / 1e6:.0f} MB; process peak resident memory {rss_mb:.0f} MB")
    first, best = totals[0], min(totals)
    print(f"first report {first:.1f} s, best {best:.1f} s: target <= {TARGET_S:.0f} s {'met' if first <= TARGET_S else 'MISSED'}")


if __name__ == "__main__":
    main()
