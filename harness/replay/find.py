"""Finding an episode's recording in a run folder (``cfharness replay RUN EPISODE``)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

from conceptfusion.errors import ConceptFusionError, HarnessError, MissingFileError, UnknownNameError
from conceptfusion.names import unknown_name_error
from harness.replay.record import is_recording_file, read_header
from harness.report.paths import REPLAYS_DIR
from harness.runner.results import load_results, read_run_config

__all__ = ["list_recordings", "find_recording"]

_LOG = logging.getLogger(__name__)


def list_recordings(run_dir: str | os.PathLike) -> list[tuple[Path, dict]]:
    """Every readable recording of a run folder with its header, by file name; unreadable ones
    are logged and left out."""
    folder = Path(run_dir) / REPLAYS_DIR
    out = []
    for path in sorted(folder.glob("*.npz")) if folder.is_dir() else []:
        if not is_recording_file(path):
            continue
        try:
            out.append((path, read_header(path)))
        except (ConceptFusionError, OSError) as exc:
            _LOG.warning("skipping %s: %s", path, exc)
    return out


def _describe(path: Path, h: dict) -> str:
    return f"suite {h.get('suite')} agent {h.get('agent_label', h.get('agent'))} seed {h.get('seed')} ({path.name})"


def _not_recorded(run_dir: Path, episode: str, suite, agent, seed) -> str:
    """Why an episode that ran has no recording, from the run's results (or "")."""
    results = run_dir / "results.jsonl"
    if not results.is_file():
        return ""
    try:
        records = [r for r in load_results(results) if str(r.get("episode_id")) == episode
                   and (suite is None or r.get("suite") == suite) and (agent is None or r.get("agent") == agent)
                   and (seed is None or r.get("seed") == seed)]
        mode = read_run_config(run_dir).get("record", "none (the run predates recordings)")
    except (ValueError, OSError):
        return ""
    if not records:
        return ""
    ok = sum(1 for r in records if r.get("status") == "ok" and (r.get("metrics") or {}).get("success"))
    n = len(records)
    head = f"episode {episode!r} ran ({n} record{'' if n == 1 else 's'}, {ok} successful) but has no recording: "
    if mode == "failures" and ok < n:
        status = ", ".join(sorted({str(r.get("status")) for r in records if r.get("status") != "ok"})) or "ok"
        return head + (f"an episode that times out or whose worker dies leaves none (status: {status}; "
                       "see its error in results.jsonl)")
    kept = " (failures, and one success per suite and agent)" if mode == "failures" else ""
    return head + f"the run used --record {mode}{kept}; run it again with --record all to record every episode"


def find_recording(run_dir: str | os.PathLike, episode: str, *, suite: str | None = None, agent: str | None = None,
                   seed: int | None = None) -> Path:
    """The recording of ``episode`` in run folder ``run_dir``.

    ``episode`` is an episode id (matched against the recordings' headers, narrowed by ``suite``,
    ``agent`` (name or label) and ``seed``) or the path of a recording file.

    Raises:
        MissingFileError: no run folder, or a path to a recording that does not exist.
        UnknownNameError: no recording of that episode id (naming the nearest recorded ids, or
            saying why an episode that ran was not recorded).
        HarnessError: several recordings match (listing them, to pick one with suite, agent or seed).
    """
    run = Path(run_dir)
    if not run.is_dir():
        raise MissingFileError(f"run folder not found: {run}")
    as_path = Path(episode)
    if str(episode).endswith(".npz"):
        for p in (as_path, run / as_path, run / REPLAYS_DIR / as_path):
            if p.is_file():
                return p
        raise MissingFileError(f"recording not found: {episode} (looked as given, in {run} and in {run / REPLAYS_DIR})")
    recs = list_recordings(run)
    if not recs:
        why = _not_recorded(run, str(episode), suite, agent, seed)
        raise UnknownNameError(why or f"{run} holds no episode recordings (folder {run / REPLAYS_DIR}); "
                               "record with cfharness run --record failures|all")
    match = [(p, h) for p, h in recs if str(h.get("episode_id")) == str(episode)]
    if not match:
        why = _not_recorded(run, str(episode), suite, agent, seed)
        if why:
            raise UnknownNameError(why)
        ids = sorted({str(h.get("episode_id")) for _, h in recs})
        raise unknown_name_error("episode", episode, ids, listing=f"recorded episodes in {run}: {', '.join(ids)}")
    narrowed = [(p, h) for p, h in match
                if (suite is None or h.get("suite") == suite)
                and (agent is None or agent in (h.get("agent"), h.get("agent_label")))
                and (seed is None or h.get("seed") == seed)]
    if not narrowed:
        why = _not_recorded(run, str(episode), suite, agent, seed)
        if why:
            raise UnknownNameError(why)
        given = ", ".join(f"{k} {v!r}" for k, v in (("suite", suite), ("agent", agent), ("seed", seed)) if v is not None)
        raise UnknownNameError(f"episode {episode!r} has no recording with {given}; its recordings: "
                               + "; ".join(_describe(p, h) for p, h in match))
    if len(narrowed) > 1:
        raise HarnessError(f"episode {episode!r} matches {len(narrowed)} recordings; pick one with --suite, --agent or --seed: "
                           + "; ".join(_describe(p, h) for p, h in narrowed))
    return narrowed[0][0]
