"""How the report's pages link the files beside a run: replay videos and final maps.

A report written into a folder links each file by its path relative to that folder
(``../replays/<stem>.mp4``). A *bundle* (:mod:`harness.report.bundle`) copies every video a page
links into ``BUNDLE/replays/`` instead (and the maps into ``BUNDLE/maps/`` when asked), so the
links stay inside the bundle wherever it is moved.

A static page cannot start the map viewer, so a map is shown as the command that opens it
(``cfharness view <map> --encoder <encoder>``), with why it may not work here: an encoder this
install lacks, a map left out of a bundle, a record of another run than its folder's.
"""

from __future__ import annotations

import functools
import logging
import os
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from conceptfusion.io_utils import atomic_copy
from harness.report.causes import is_failure, is_scored
from harness.report.paths import MAP_SUFFIX, REPLAYS_DIR, VIDEO_SUFFIXES, replay_stem

__all__ = ["ReplayLinks", "ReportLinks", "encoder_problem", "BUNDLE_MAPS_DIR"]

_LOG = logging.getLogger(__name__)

BUNDLE_MAPS_DIR = "maps"
"""Folder inside a bundle that holds the copied maps (``--bundle-maps``)."""


@dataclass(frozen=True)
class ReplayLinks:
    """An episode's replay files as a report page links them."""

    video: str | None = None
    """Href of the replay video relative to the page's folder; None: no video to link."""
    video_note: str = ""
    """Why the video is missing (or what is odd about it); empty when nothing is."""
    map: str | None = None
    """Href of the final map file; None: absent, or left out of a bundle."""
    command: str | None = None
    """The command that opens the map in the viewer; None: the episode has no map."""
    map_note: str = ""
    """Where to run ``command`` and what may stop it working; empty when nothing."""


@functools.lru_cache(maxsize=None)
def encoder_problem(encoder: str) -> str | None:
    """Why this install cannot open a map built with ``encoder`` (unknown name, missing weights),
    or None when it can. Loads no weights (:func:`conceptfusion.perception.registry.check_encoder_files`)."""
    from conceptfusion.perception.registry import RESERVED_ENCODER_NAMES, check_encoder_files

    if str(encoder).split(":", 1)[0].strip().lower() in RESERVED_ENCODER_NAMES:
        return None
    try:
        check_encoder_files(str(encoder))
    except (ValueError, TypeError, OSError) as exc:
        return str(exc).splitlines()[0]
    except Exception as exc:  # a checkpoint error or a missing extra from a plugin's check
        return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return None


def _run_facts(run_dir: Path) -> tuple[str | None, str | None]:
    """(the run id, the record mode) its ``run.json`` names; None for what it does not say."""
    from harness.runner.results import read_run_config

    try:
        config = read_run_config(run_dir)
    except (OSError, ValueError):
        return None, None
    run_id, mode = config.get("run_id"), config.get("record")
    return (run_id if isinstance(run_id, str) else None), (mode if isinstance(mode, str) else None)


@dataclass
class ReportLinks:
    """Links from report pages written into ``out_dir`` to the files beside the runs.

    ``bundle``: copy each linked video into ``out_dir/replays/`` (and, with ``bundle_maps``, each
    map into ``out_dir/maps/``) and link the copy, so every link stays inside ``out_dir``.
    """

    out_dir: Path
    bundle: bool = False
    bundle_maps: bool = False
    copied: dict[Path, Path] = field(default_factory=dict)
    """Source file -> its copy inside the bundle."""
    _facts: dict[Path, tuple[str | None, str | None]] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.out_dir = Path(self.out_dir)
        if self.bundle_maps and not self.bundle:
            raise ValueError("ReportLinks: bundle_maps=True needs bundle=True (maps are only copied into a bundle)")

    def href(self, target: Path) -> str:
        """``target`` relative to ``out_dir``, URL-quoted with ``/`` separators."""
        rel = os.path.relpath(Path(target).resolve(), self.out_dir.resolve())
        return quote(rel.replace(os.sep, "/"))

    def _copy(self, src: Path, folder: str) -> Path:
        if src in self.copied:
            return self.copied[src]
        taken = set(self.copied.values())
        dst, i = self.out_dir / folder / src.name, 1
        while dst in taken:
            i += 1
            ext = MAP_SUFFIX if src.name.endswith(MAP_SUFFIX) else src.suffix
            dst = self.out_dir / folder / f"{src.name[:len(src.name) - len(ext)]}-{i}{ext}"
        self.copied[src] = atomic_copy(src, dst)
        return dst

    def _run(self, run_dir: Path) -> tuple[str | None, str | None]:
        if run_dir not in self._facts:
            self._facts[run_dir] = _run_facts(run_dir)
        return self._facts[run_dir]

    def replay(self, record: dict, run_dir: str | os.PathLike | None) -> ReplayLinks:
        """The links to an episode's replay video and map (``RUN/replays/<stem>.*``, see
        :func:`harness.report.paths.replay_stem`), with notes on what is missing and why.
        ``run_dir`` None (records passed without a folder): nothing is found, nothing noted."""
        if run_dir is None:
            return ReplayLinks()
        run = Path(run_dir)
        folder, stem = run / REPLAYS_DIR, replay_stem(record)
        video = next((folder / f"{stem}{s}" for s in VIDEO_SUFFIXES if (folder / f"{stem}{s}").is_file()), None)
        map_path = folder / f"{stem}{MAP_SUFFIX}"
        run_id, mode = self._run(run)
        foreign = ""
        if run_id is not None and record.get("run_id") not in (None, run_id):
            foreign = (f"this record is of run {record.get('run_id')}, the folder's run.json names run {run_id}: "
                       "the files under this episode's name may be the other run's")
        notes = [foreign] if foreign else []
        if video is not None:
            href = self.href(self._copy(video, REPLAYS_DIR) if self.bundle else video)
        else:
            href = None
            recording = folder / f"{stem}.npz"
            if recording.is_file():
                notes.insert(0, f"no video: the recording {REPLAYS_DIR}/{recording.name} has none yet "
                                f"(cfharness report or cfharness replay renders it)")
            elif (mode == "all" and is_scored(record)) or (mode == "failures" and is_scored(record) and is_failure(record)):
                notes.insert(0, f"missing: the run recorded {mode} (run.json), but {REPLAYS_DIR}/{stem}.mp4 and its "
                                "recording are not in the run folder (deleted or moved?)")
        links = {"video": href, "video_note": "; ".join(notes)}
        if not map_path.is_file():
            return ReplayLinks(**links)
        return ReplayLinks(**links, **self._map(record, run, map_path, foreign))

    def _map(self, record: dict, run: Path, map_path: Path, foreign: str) -> dict:
        encoder = str(record.get("encoder"))
        notes = []
        if self.bundle and self.bundle_maps:
            copy = self._copy(map_path, BUNDLE_MAPS_DIR)
            href, shown = self.href(copy), copy.relative_to(self.out_dir).as_posix()
            notes.append("run it in this report's folder")
        elif self.bundle:
            href, shown = None, map_path.relative_to(run).as_posix()
            notes.append(f"run it in the run folder {run} (maps are left out of this bundle; "
                         "cfharness report --bundle-maps copies them)")
        else:
            href, shown = self.href(map_path), str(map_path.resolve())
        problem = encoder_problem(encoder)
        if problem:
            notes.append(f"encoder {encoder!r} is not available in this install ({problem}): the viewer needs "
                         "the encoder the map was built with")
        if foreign:
            notes.append(foreign)
        command = f"cfharness view {shlex.quote(shown)} --encoder {shlex.quote(encoder)}"
        return {"map": href, "command": command, "map_note": "; ".join(notes)}
