"""The committed calibration records are still what the code does: a sample of them, run again."""

import pytest

from harness.runner.bounds import regression_suites, replay_sample
from harness.runner.suites import HEADLINE_GATE


@pytest.mark.gate
@pytest.mark.parametrize("suite", [s for s in regression_suites() if s.name not in HEADLINE_GATE], ids=lambda s: s.name)
def test_a_sample_of_calibration_episodes_comes_back_exactly(suite):
    # every agent's first calibration episode and one more spread by hash: status and every metric equal
    # (the headline suites' in test_headline_gate.py, with the rest of their gate)
    assert replay_sample(suite, per_agent=2) == []


def test_a_stale_record_is_named(tmp_path):
    import json

    from harness.runner.bounds import RECORDS_DIR, _regression_suite, records_file

    suite = _regression_suite("regression-rearrange")
    lines = records_file(suite).read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if '"agent":"random-pusher"' in line)
    rec = json.loads(lines[first])
    rec["metrics"]["steps"] += 1
    lines[first] = json.dumps(rec)
    (tmp_path / records_file(suite).name).write_text("\n".join(lines) + "\n")
    problems = replay_sample(suite, per_agent=1, folder=tmp_path, agents=("random-pusher",))
    assert problems == [f"regression-rearrange random-pusher {rec['episode_id']}: metrics.steps {rec['metrics']['steps']} committed, "
                        f"{rec['metrics']['steps'] - 1} now"]
    assert replay_sample(suite, per_agent=1, folder=RECORDS_DIR, agents=("random-pusher",)) == []
