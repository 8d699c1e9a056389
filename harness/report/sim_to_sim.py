"""Do an agent's results survive a change of simulator? The same episodes in MuJoCo and PyBullet.

A suite ``S`` runs in MuJoCo; its variant ``S-pybullet`` (:data:`PYBULLET_SUFFIX`) runs the same
episodes with the same agents and settings in PyBullet (other renderer, other lighting and
textures; the shipped tower was trained on MuJoCo renders only). :func:`sim_to_sim` pairs their
records per agent and perception by episode and seed: each simulator's success with its Wilson
interval, the paired difference (PyBullet minus MuJoCo) with a bootstrap interval, and the exact
McNemar p.

``cfharness develop sim-to-sim RUN... --write`` measures it once for the README: the PyBullet run
folders of ``search-v2-pybullet``, paired with the MuJoCo records of the sealed headline
(:data:`~harness.report.headline.RECORDS_FILE`); it keeps the stripped records of both in
:data:`RECORDS_FILE` and writes the README's table between its markers; a test recomputes the
table from that file.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from conceptfusion.errors import HarnessError
from harness.report.headline import read_kept_records, replace_between_markers
from harness.report.stats import bootstrap_ci, mcnemar_exact, metric_value, wilson_interval
from harness.runner.results import latest_records, load_results

__all__ = ["PYBULLET_SUFFIX", "RECORDS_FILE", "SimPair", "sim_to_sim", "sim_to_sim_table", "readme_with_table", "main"]

PYBULLET_SUFFIX = "-pybullet"
"""A suite's PyBullet variant is named ``<suite>-pybullet``."""
RECORDS_FILE = Path(__file__).resolve().parents[1] / "data" / "sim_to_sim" / "records.jsonl"
README_START = "<!-- sim-to-sim table: cfharness develop sim-to-sim RUN... --write -->"
README_END = "<!-- end of the sim-to-sim table -->"


@dataclass(frozen=True)
class SimPair:
    """One agent and perception on the same episodes in both simulators."""

    suite: str
    """The MuJoCo suite (its PyBullet variant is ``suite + PYBULLET_SUFFIX``)."""
    agent: str
    encoder: str
    privileged: bool
    n: int
    """Episodes (and seeds) run in both."""
    mujoco: int
    pybullet: int
    diff: float
    """PyBullet minus MuJoCo success rate."""
    ci: tuple[float, float]
    p: float

    def rate(self, k: int) -> tuple[float, float, float]:
        lo, hi = wilson_interval(k, self.n)
        return k / self.n, lo, hi


def _flags(records: list[dict]) -> dict[tuple, bool]:
    return {(r["episode_id"], r["seed"]): bool(metric_value(r, "success")) for r in records}


def sim_to_sim(records: list[dict]) -> list[SimPair]:
    """Every (suite, agent, encoder) with records in a suite and in its PyBullet variant, paired
    on the episodes (and seeds) both ran; a newer record of an episode replaces an older one.

    Raises:
        HarnessError: no suite has records in both simulators.
    """
    records = latest_records(records)
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r["suite"], r["agent"], r["encoder"]), []).append(r)
    out = []
    for (suite, agent, enc), recs in sorted(groups.items()):
        if suite.endswith(PYBULLET_SUFFIX) or (suite + PYBULLET_SUFFIX, agent, enc) not in groups:
            continue
        a, b = _flags(recs), _flags(groups[(suite + PYBULLET_SUFFIX, agent, enc)])
        keys = sorted(set(a) & set(b))
        if not keys:
            continue
        xa = np.array([a[k] for k in keys], float)
        xb = np.array([b[k] for k in keys], float)
        lo, hi = bootstrap_ci(xb - xa)
        only_b, only_a = int(((xb == 1) & (xa == 0)).sum()), int(((xa == 1) & (xb == 0)).sum())
        privileged = any((r.get("extras") or {}).get("privileged") for r in recs)
        out.append(SimPair(suite, agent, enc, privileged, len(keys), int(xa.sum()), int(xb.sum()),
                           float(xb.mean() - xa.mean()), (float(lo), float(hi)), mcnemar_exact(only_b, only_a)))
    if not out:
        raise HarnessError("sim-to-sim: expected records of a suite and of its PyBullet variant (<suite>-pybullet) for the "
                           "same agent and perception; found none")
    return out


def sim_to_sim_table(pairs: list[SimPair]) -> str:
    """The pairs as a Markdown table (rates with Wilson intervals; the difference with its bootstrap interval)."""
    rows = ["| suite | agent | perception | MuJoCo | PyBullet | PyBullet - MuJoCo [95% CI] | McNemar p | n |",
            "|---|---|---|---|---|---|---|---|"]
    for s in pairs:
        cells = []
        for k in (s.mujoco, s.pybullet):
            rate, lo, hi = s.rate(k)
            cells.append(f"{k}/{s.n} = {rate:.2f} [{lo:.2f}, {hi:.2f}]")
        enc = f"{s.encoder} (privileged)" if s.privileged else s.encoder
        rows.append(f"| `{s.suite}` | {s.agent} | {enc} | {cells[0]} | {cells[1]} | {s.diff:+.2f} [{s.ci[0]:+.2f}, "
                    f"{s.ci[1]:+.2f}] | {s.p:.2g} | {s.n} |")
    return "\n".join(rows)


def readme_with_table(readme: str, table: str) -> str:
    """``readme`` with the text between :data:`README_START` and :data:`README_END` replaced by ``table``."""
    return replace_between_markers(readme, README_START, README_END, table, "sim-to-sim table")


def main(argv: list[str] | None = None) -> int:
    from harness.report.headline import RECORDS_FILE as SEALED_RECORDS, strip_record, write_measurement

    p = argparse.ArgumentParser(prog="cfharness develop sim-to-sim", description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="run folders of <suite>-pybullet runs (and of their MuJoCo suite, when the "
                   "sealed records do not hold it)")
    p.add_argument("--write", action="store_true", help=f"keep the records in {RECORDS_FILE} and write the README's table")
    args = p.parse_args(argv)
    try:
        runs = [strip_record(r) for run in args.runs for r in load_results(Path(run) / "results.jsonl")]
        pyb = {(r["suite"][: -len(PYBULLET_SUFFIX)], r["agent"], r["encoder"]) for r in runs
               if r["suite"].endswith(PYBULLET_SUFFIX)}
        mujoco = [r for r in read_kept_records(SEALED_RECORDS) if (r["suite"], r["agent"], r["encoder"]) in pyb]
        table = sim_to_sim_table(sim_to_sim(mujoco + runs))
    except (HarnessError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(table)
    if args.write:
        return write_measurement(RECORDS_FILE, mujoco + runs, table, README_START, README_END, "sim-to-sim table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
