"""Longest jobs first: the pool backends' order, and the rough lengths jobs declare."""

from __future__ import annotations

from types import SimpleNamespace

from harness.runner.jobs import expected_seconds, longest_first
from harness.runner.map_jobs import map_suite_jobs
from harness.runner.run import RunConfig, episode_jobs
from harness.runner.suites import get_suite


def test_longest_first_keeps_the_order_of_ties_and_reads_missing_or_bad_lengths_as_one_second():
    jobs = [SimpleNamespace(expected_s=2.0), SimpleNamespace(), SimpleNamespace(expected_s=20.0),
            SimpleNamespace(expected_s="slow"), SimpleNamespace(expected_s=-3.0), SimpleNamespace(expected_s=float("inf")),
            SimpleNamespace(expected_s=2.0), SimpleNamespace(expected_s=0.5)]
    assert [expected_seconds(j) for j in jobs] == [2.0, 1.0, 20.0, 1.0, 1.0, 1.0, 2.0, 0.5]
    assert longest_first(jobs) == [2, 0, 6, 1, 3, 4, 5, 7]
    assert longest_first([]) == []


def test_search_episodes_of_map_agents_start_before_short_jobs():
    config = RunConfig(suites=("rearrange", "search", "ablation"), limit=1)
    jobs = (episode_jobs(get_suite("rearrange"), config, "r") + episode_jobs(get_suite("search"), config, "r")
            + map_suite_jobs("ablation", config, "r"))
    first = [jobs[i] for i in longest_first(jobs)]
    assert [j.agent for j in first[:3]] == ["map-navigator", "frame-searcher", "map-pusher"]
    assert first[-1].agent == "random-walker" or first[-1].suite == "ablation"
    assert all(expected_seconds(j) > 0 for j in jobs)


def test_every_job_runs_with_one_blas_thread_and_the_callers_count_comes_back():
    import subprocess
    import sys

    code = (
        "import numpy, threadpoolctl\n"
        "from harness.runner.backends import run_jobs\n"
        "def blas():\n"
        "    return sorted({i['num_threads'] for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas'})\n"
        "class J:\n"
        "    run_id, suite, timeout_s, plugins, task, label = 'r', 's', 60.0, (), 't', 'probe'\n"
        "    def key_record(self): return {}\n"
        "    def failure_record(self, status, error, wall_s): return {'status': status}\n"
        "    def run(self): return [{'blas': blas()}]\n"
        "before = blas()\n"
        "inside = [r['blas'] for r in run_jobs([J()], backend='serial')]\n"
        "print(before, inside, blas())\n"
    )
    env = {**__import__("os").environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout.strip()
    assert out == "[2] [[1]] [2]", out
