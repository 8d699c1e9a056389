"""The sealed test set: episodes and scenes no decision may read, and the manifest that pins them.

``scenes/sealed-v2/`` (written by ``python -m scenes.make_sealed_v2``) holds apartments, tables and
episodes drawn on the split file's ``sealed`` seeds. Two rules keep it a test set:

* **Pinned**: ``MANIFEST.json`` records, for every scene file, a SHA-256 per top-level field and,
  for every episode line of the episode files, a SHA-256 per field. :func:`verify_sealed` checks a
  sealed episode file and the scenes its episodes use against it before any episode runs, and
  refuses a difference naming the file, the line (episode files) and the field.
* **Unread by development**: every command that chooses something (agent development runs,
  score-floor and regression-floor calibration, the map suites' development scripts, tower
  training and selection) passes what it is about to read through :func:`refuse_sealed`, which
  refuses any episode or scene of the sealed folder or of a ``sealed`` seed, wherever the file
  was copied to.

Headline figures are measured on it once, after the choices are frozen
(``harness/data/sealed/measured.json`` says by which commit and run).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Iterable, Mapping

from conceptfusion.errors import SimError
from conceptfusion.io_utils import MAX_EPISODES_BYTES, MAX_SCENE_BYTES, read_json_document, read_text_file
from conceptfusion.strict_json import loads_strict
from sim_envs.scenes.episodes import SCENES_ROOT, Episode, check_scene_ref, load_episodes
from sim_envs.scenes.splits import splits

__all__ = ["SEALED_FOLDER_NAME", "SEALED_FOLDER", "MANIFEST_NAME", "SEALED_SEED_ROLE", "SealedSetError", "manifest_text", "is_sealed_file",
           "is_sealed_seed", "refuse_sealed", "refuse_sealed_episodes", "verify_sealed"]

SEALED_FOLDER_NAME = "sealed-v2"
SEALED_FOLDER = SCENES_ROOT / SEALED_FOLDER_NAME
"""The sealed set's folder."""
MANIFEST_NAME = "MANIFEST.json"
SEALED_SEED_ROLE = "sealed"
"""The split file's seed role of sealed scenes."""

_HEX = 16
"""Hex digits kept of each SHA-256 (64 bits: a change goes unnoticed with probability 2**-64)."""


class SealedSetError(SimError):
    """A development command reached for the sealed set, or a sealed file differs from its manifest."""


def _digest(value) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode()).hexdigest()[:_HEX]


def _field_digests(obj: Mapping) -> dict[str, str]:
    return {k: _digest(v) for k, v in sorted(obj.items())}


def manifest_text(files: Mapping[str, str], *, episode_files: Iterable[str]) -> str:
    """The manifest of a sealed folder's files (path relative to ``scenes/`` -> text): per episode
    file, its header's and each episode line's field digests (by line number); per scene file,
    its top-level field digests."""
    episode_files = set(episode_files)
    out: dict = {"format": "cf-sealed-manifest", "version": 1, "episode_files": {}, "scene_files": {}}
    for path in sorted(files):
        text = files[path]
        if path in episode_files:
            lines = {str(no): _field_digests(json.loads(line)) for no, line in enumerate(text.splitlines(), start=1) if line.strip()}
            out["episode_files"][path] = lines
        elif path.endswith(".json") and not path.endswith(MANIFEST_NAME):
            out["scene_files"][path] = _field_digests(json.loads(text))
    return json.dumps(out, indent=1, sort_keys=True) + "\n"


def is_sealed_seed(seed) -> bool:
    """Whether ``seed`` lies in the split file's ``sealed`` seed range."""
    try:
        return splits().seed_role(int(seed)) == SEALED_SEED_ROLE
    except (TypeError, ValueError):
        return False


def is_sealed_file(path) -> bool:
    """Whether ``path`` (absolute, or relative to ``scenes/``) lies in the sealed folder."""
    p = Path(path)
    if not p.is_absolute():
        p = SCENES_ROOT / p
    try:
        p.resolve().relative_to(SEALED_FOLDER.resolve())
        return True
    except ValueError:
        return False


def refuse_sealed(what, who: str) -> None:
    """Refuse to let ``who`` (a development command) read the sealed set.

    ``what``: a path (an episode file, a scene file or a folder), an :class:`Episode`, a scene
    seed (int), or an iterable of these.

    Raises:
        SealedSetError: naming ``who`` and the first sealed item.
    """
    items = [what] if isinstance(what, (str, Path, Episode, int)) else list(what)
    for item in items:
        reason = None
        if isinstance(item, Episode):
            if is_sealed_file(item.scene) or is_sealed_seed(item.scene_seed):
                reason = f"episode {item.episode_id!r} (scene {item.scene}, seed {item.scene_seed})"
        elif isinstance(item, int) and not isinstance(item, bool):
            if is_sealed_seed(item):
                reason = f"scene seed {item} (the split file's {SEALED_SEED_ROLE!r} range)"
        elif is_sealed_file(item):
            reason = f"{item}"
        if reason is not None:
            raise SealedSetError(f"{who}: refusing to read the sealed test set: {reason} is sealed "
                                 f"({SEALED_FOLDER_NAME}, seeds {list(splits().seeds[SEALED_SEED_ROLE])}); development "
                                 "chooses on the calibration and validation sets only")


def refuse_sealed_episodes(path, who: str) -> None:
    """:func:`refuse_sealed` for an episode file: the file itself and every episode in it (a copy
    of sealed episodes elsewhere still lies on sealed seeds).

    Raises:
        SealedSetError: naming ``who`` and the first sealed item.
    """
    refuse_sealed(path, who)
    refuse_sealed(load_episodes(path).episodes, who)


def _manifest(folder: Path) -> dict:
    return read_json_document(folder / MANIFEST_NAME, fmt="cf-sealed-manifest", version=1, what="manifest", error=SealedSetError,
                              missing="the sealed set has no manifest; regenerate it with python -m scenes.make_sealed_v2")


def _compare(where: str, want: Mapping, obj) -> None:
    if not isinstance(obj, dict):
        raise SealedSetError(f"{where}: expected a JSON object as the manifest records, got {type(obj).__name__}")
    got = _field_digests(obj)
    for key in sorted(set(want) | set(got)):
        if key not in got:
            raise SealedSetError(f"{where}: field {key!r} is missing (the manifest records it)")
        if key not in want:
            raise SealedSetError(f"{where}: field {key!r} is not in the manifest")
        if got[key] != want[key]:
            raise SealedSetError(f"{where}: field {key!r} differs from its recorded hash")


def verify_sealed(episode_file, scenes=()) -> None:
    """Check a sealed episode file, and the scene files ``scenes`` (paths relative to ``scenes/``),
    against the sealed folder's manifest.

    Raises:
        SealedSetError: no or a malformed manifest; a file the manifest does not record; a line
            added, missing or changed; a field of a line or scene that differs from its recorded
            hash (naming file, line and field).
    """
    path = Path(episode_file)
    data = _manifest(SEALED_FOLDER)
    rel = path.resolve().relative_to(SCENES_ROOT.resolve()).as_posix()
    lines = data["episode_files"].get(rel)
    if lines is None:
        raise SealedSetError(f"{path}: not an episode file of the sealed set's manifest")
    seen = set()
    text = read_text_file(path, "episode file", SealedSetError, max_bytes=MAX_EPISODES_BYTES)
    for no, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        where = f"{path}:line {no}"
        want = lines.get(str(no))
        if want is None:
            raise SealedSetError(f"{where}: a line the manifest does not record")
        try:
            obj = loads_strict(line, source=str(path), line=no, error=SealedSetError)
        except json.JSONDecodeError as exc:
            raise SealedSetError(f"{where}: not valid JSON ({exc.msg})") from None
        _compare(where, want, obj)
        seen.add(str(no))
    missing = sorted(set(lines) - seen, key=int)
    if missing:
        raise SealedSetError(f"{path}:line {missing[0]}: missing (the manifest records {len(lines)} lines)")
    for scene in sorted(set(scenes)):
        want = data["scene_files"].get(scene)
        if want is None:
            raise SealedSetError(f"{SCENES_ROOT / scene}: not a scene file of the sealed set's manifest")
        try:
            check_scene_ref(scene)
            text = read_text_file(SCENES_ROOT / scene, "scene file", SealedSetError, max_bytes=MAX_SCENE_BYTES)
            obj = loads_strict(text, source=str(SCENES_ROOT / scene), error=SealedSetError)
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise SealedSetError(f"{SCENES_ROOT / scene}: cannot be read as JSON ({exc})") from None
        _compare(str(SCENES_ROOT / scene), want, obj)
