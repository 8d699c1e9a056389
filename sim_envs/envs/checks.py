"""What the environments check at their public boundary: constructor arguments, ``reset``
arguments and episodes, actions, and when ``step`` may be called.

**Episode lifecycle** (:class:`EpisodeLifecycle`, the Gymnasium convention): ``step()`` raises
:class:`~conceptfusion.errors.EnvStateError` before the first successful ``reset()``, after a
step returned ``terminated`` or ``truncated``, after a ``reset()`` that failed part-way and
after ``close()``, until the next successful ``reset()``.

**Reset options** (:func:`check_reset_options`): ``None`` or a dict whose keys the environment
names in ``reset_option_keys``; an unknown key raises
:class:`~conceptfusion.errors.UnknownNameError` naming the nearest valid ones. The episode
options shared by the tasks with episode records (:func:`episode_from_options`):
``{"episode": Episode}`` or ``{"episode_index": i}`` (an index into the environment's episode
set), not both.

Every other refusal is a :class:`~conceptfusion.errors.SimError` (a ``ValueError``), or a
:class:`~conceptfusion.errors.SimTypeError` (also a ``TypeError``) for a value of the wrong
type; messages name the environment, the argument, what was expected and what arrived.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from conceptfusion.errors import EnvStateError, MissingFileError, SimError, SimTypeError, UnknownNameError
from conceptfusion.names import did_you_mean
from sim_envs.scenes.episodes import Episode, EpisodeSet, Goal, load_episodes

__all__ = [
    "check_bool",
    "MAX_IMAGE_SIDE",
    "EpisodeLifecycle",
    "check_int",
    "check_number",
    "check_image_size",
    "check_fovy",
    "check_choice",
    "check_scenes_root",
    "check_episode_set",
    "check_reset_seed",
    "check_reset_options",
    "episode_from_options",
    "check_episode",
    "check_action",
]

MAX_IMAGE_SIDE = 8192
"""The largest image width or height an environment renders (pixels); larger sizes are refused
before an offscreen buffer is asked for."""

_NEW, _RUNNING, _OVER, _CLOSED = "new", "running", "over", "closed"


# --------------------------------------------------------------------------- lifecycle
class EpisodeLifecycle:
    """Mixin (put it before ``gym.Env``) that refuses ``step()`` outside an episode.

    The environment names itself in ``env_name`` and its reset option keys in
    ``reset_option_keys``, and calls, in ``reset``: :meth:`_begin_reset` first (checks the seed
    and options, then marks the environment as needing a reset, so a reset that fails part-way
    leaves it refusing steps) and :meth:`_episode_started` last; in ``step``:
    :meth:`_check_step` first and :meth:`_step_done` with the step's flags. ``close()`` marks
    it closed and calls the next ``close()`` in the MRO.
    """

    env_name: str = "environment"
    reset_option_keys: tuple[str, ...] = ()
    _phase: str = _NEW

    def _begin_reset(self, seed: Any, options: Any) -> tuple[int | None, dict[str, Any]]:
        """The checked ``(seed, options)`` of a ``reset`` call (options as a new dict)."""
        seed = check_reset_seed(self.env_name, seed)
        opts = check_reset_options(self.env_name, options, self.reset_option_keys)
        self._phase = _NEW
        return seed, opts

    def _episode_started(self) -> None:
        """Mark the reset as done: steps are allowed until one ends the episode."""
        self._phase = _RUNNING

    def _check_step(self) -> None:
        """Raise :class:`EnvStateError` unless an episode is running."""
        if self._phase == _RUNNING:
            return
        why = {
            _NEW: "step() before a successful reset()",
            _OVER: "the episode is over (a step returned terminated or truncated)",
            _CLOSED: "the environment was closed",
        }[self._phase]
        raise EnvStateError(f"{self.env_name}: {why}; call reset() to start an episode")

    def _require_reset(self, what: str) -> None:
        """Raise :class:`EnvStateError` for ``what`` (a method name) unless an episode was set
        up by a successful ``reset()`` (running or over) and the environment is not closed."""
        if self._phase in (_NEW, _CLOSED):
            state = "closed" if self._phase == _CLOSED else "not reset"
            raise EnvStateError(f"{self.env_name}: {what} needs an episode (the environment is {state}); call reset() first")

    def _step_done(self, terminated: bool, truncated: bool) -> None:
        """Record a step's outcome: the episode is over once either flag is set."""
        if terminated or truncated:
            self._phase = _OVER

    def close(self) -> None:
        """Mark the environment closed (steps refused until ``reset``), then release it."""
        self._phase = _CLOSED
        super().close()  # type: ignore[misc]


# --------------------------------------------------------------------------- constructor arguments
def check_bool(where: str, name: str, value: Any) -> bool:
    """``value`` as a ``bool``; anything but ``True``, ``False`` (or a numpy bool) is refused."""
    if not isinstance(value, (bool, np.bool_)):
        raise SimTypeError(f"{where}: {name}: expected True or False, got {value!r}")
    return bool(value)


def check_int(where: str, name: str, value: Any, *, minimum: int, allow_none: bool = False) -> int | None:
    """``value`` as an ``int`` >= ``minimum`` (``None`` passes with ``allow_none``); bools,
    floats and strings are refused."""
    if value is None and allow_none:
        return None
    expected = f"{'None or ' if allow_none else ''}an int >= {minimum}"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise SimTypeError(f"{where}: {name}: expected {expected}, got {type(value).__name__} {value!r}")
    if value < minimum:
        raise SimError(f"{where}: {name}: expected {expected}, got {value!r}")
    return int(value)


def check_number(
    where: str, name: str, value: Any, *, low: float | None = None, high: float | None = None,
    low_open: bool = False, high_open: bool = False,
) -> float:
    """``value`` as a finite ``float`` within the given bounds (open or closed)."""
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    expected = "a finite number" + (" " + " and ".join(parts) if parts else "")
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SimTypeError(f"{where}: {name}: expected {expected}, got {type(value).__name__} {value!r}")
    v = float(value)
    ok = math.isfinite(v)
    if ok and low is not None:
        ok = v > low if low_open else v >= low
    if ok and high is not None:
        ok = v < high if high_open else v <= high
    if not ok:
        raise SimError(f"{where}: {name}: expected {expected}, got {value!r}")
    return v


def check_image_size(where: str, width: Any, height: Any, *, prefix: str = "", allow_none: bool = False) -> tuple[int | None, int | None]:
    """``(width, height)`` as ints in ``[1, MAX_IMAGE_SIDE]`` (``None`` passes with ``allow_none``)."""
    out = []
    for name, value in ((f"{prefix}width", width), (f"{prefix}height", height)):
        v = check_int(where, name, value, minimum=1, allow_none=allow_none)
        if v is not None and v > MAX_IMAGE_SIDE:
            raise SimError(f"{where}: {name}: expected at most {MAX_IMAGE_SIDE} pixels, got {v}")
        out.append(v)
    return out[0], out[1]


def check_fovy(where: str, fovy_deg: Any) -> float:
    """A vertical field of view in degrees, in the open interval (0, 180)."""
    return check_number(where, "fovy_deg", fovy_deg, low=0.0, high=180.0, low_open=True, high_open=True)


def check_choice(where: str, name: str, value: Any, choices: Mapping[str, Any] | Sequence[str]) -> str:
    """``value`` when it is one of ``choices`` (a str); else
    :class:`~conceptfusion.errors.UnknownNameError` naming them and the nearest one."""
    if isinstance(value, str) and value in choices:
        return value
    hint = did_you_mean(value, choices, n=1, cutoff=0.6) if isinstance(value, str) else ""
    raise UnknownNameError(f"{where}: {name}: expected one of {sorted(choices)}, got {value!r}{hint}")


def check_scenes_root(where: str, scenes_root: Any) -> str | os.PathLike | None:
    """``None`` or an existing folder (str or path)."""
    if scenes_root is None:
        return None
    if not isinstance(scenes_root, (str, os.PathLike)):
        raise SimTypeError(f"{where}: scenes_root: expected None or a folder path, got {type(scenes_root).__name__}")
    if not Path(scenes_root).is_dir():
        raise MissingFileError(f"{where}: scenes_root: no folder {str(scenes_root)!r}")
    return scenes_root


def check_episode_set(where: str, episodes: Any, task: str, *, scenes_root=None) -> EpisodeSet | tuple[Episode, ...] | None:
    """The episodes given to a constructor: ``None``, an episode file path (loaded with
    :func:`~sim_envs.scenes.episodes.load_episodes`), an :class:`EpisodeSet` or a sequence of
    :class:`Episode`; a file or set must be of ``task`` and none may be empty."""
    if episodes is None:
        return None
    if isinstance(episodes, (str, os.PathLike)):
        if not Path(episodes).is_file():
            raise MissingFileError(f"{where}: episodes: no episode file {str(episodes)!r}")
        episodes = load_episodes(episodes, scenes_root=scenes_root)
    if isinstance(episodes, EpisodeSet):
        if episodes.task != task:
            raise SimError(f"{where}: episodes: expected task {task!r}, got {episodes.task!r}")
        if not episodes.episodes:
            raise SimError(f"{where}: episodes: the episode set holds no episodes")
        return episodes
    if isinstance(episodes, Sequence) and not isinstance(episodes, (str, bytes)):
        if not episodes:
            raise SimError(f"{where}: episodes: expected at least one Episode (or None), got an empty {type(episodes).__name__}")
        for i, ep in enumerate(episodes):
            if not isinstance(ep, Episode):
                raise SimTypeError(f"{where}: episodes[{i}]: expected an Episode, got {type(ep).__name__}")
        return tuple(episodes)
    raise SimTypeError(
        f"{where}: episodes: expected None, an episode file path, an EpisodeSet or a list of Episode, got {type(episodes).__name__}"
    )


# --------------------------------------------------------------------------- reset
def check_reset_seed(where: str, seed: Any) -> int | None:
    """``None`` or an int >= 0 (numpy integers become ``int``)."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise SimTypeError(f"{where}: seed: expected None or an int >= 0, got {type(seed).__name__} {seed!r}")
    if seed < 0:
        raise SimError(f"{where}: seed: expected None or an int >= 0, got {seed!r}")
    return int(seed)


def check_reset_options(where: str, options: Any, keys: Sequence[str]) -> dict[str, Any]:
    """``options`` as a new dict after checking it is ``None`` or a dict with only ``keys``."""
    valid = ", ".join(repr(k) for k in keys) if keys else "none"
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise SimTypeError(f"{where}: options: expected None or a dict (valid keys: {valid}), got {type(options).__name__}")
    for key in options:
        if key not in keys:
            hint = did_you_mean(key, keys) if isinstance(key, str) else ""
            listing = f"valid keys: {valid}" if keys else f"{where} takes no reset options"
            raise UnknownNameError(f"{where}: unknown reset option {key!r}{hint} ({listing})")
    return dict(options)


def episode_from_options(where: str, options: Mapping[str, Any], episodes: Sequence[Episode] | None, rng: np.random.Generator) -> Episode | None:
    """The episode a reset asks for: ``options["episode"]``; else ``episodes[options["episode_index"]]``;
    else one of ``episodes`` drawn with ``rng``; else ``None`` (no episodes: the environment
    makes one up). With ``episodes`` one index is drawn from ``rng`` whether or not
    ``episode_index`` is given (so the generator's later draws do not depend on it)."""
    if "episode" in options and "episode_index" in options:
        raise SimError(f"{where}: options: give 'episode' or 'episode_index', not both")
    if "episode" in options:
        ep = options["episode"]
        if not isinstance(ep, Episode):
            raise SimTypeError(f"{where}: options['episode']: expected an Episode, got {type(ep).__name__}")
        return ep
    if not episodes:
        if "episode_index" in options:
            raise SimError(f"{where}: options['episode_index']: the environment has no episode set; give episodes= to the constructor")
        return None
    n = len(episodes)
    drawn = int(rng.integers(n))
    i = options.get("episode_index", drawn)
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < n:
        raise SimError(f"{where}: options['episode_index']: expected an integer in [0, {n}), got {i!r}")
    return episodes[int(i)]


def check_episode(where: str, ep: Episode, *, charset: str, max_instruction: int, search: bool) -> Episode:
    """Check the fields of an episode record built in code (files are checked by
    :func:`~sim_envs.scenes.episodes.load_episodes`): types, at least one goal, ``max_steps``
    >= 1, the instruction's length and characters (the observation space's), and for a search
    task (``search``) a finite start pose ``(x, y, yaw)``, for a rearrangement every goal's side."""
    name = f"{where}: episode {getattr(ep, 'episode_id', '?')!r}"
    for field, kind in (("episode_id", str), ("scene", str), ("instruction", str)):
        if not isinstance(getattr(ep, field), kind):
            raise SimTypeError(f"{name}: {field}: expected a str, got {type(getattr(ep, field)).__name__}")
    for field in ("scene_seed", "max_steps"):
        check_int(name, field, getattr(ep, field), minimum=0 if field == "scene_seed" else 1)
    goals = ep.goals
    if not isinstance(goals, (tuple, list)) or not goals or not all(isinstance(g, Goal) and isinstance(g.object_id, str) for g in goals):
        raise SimError(f"{name}: goals: expected a non-empty tuple of Goal(object_id: str, ...), got {goals!r}")
    if not search and any(g.side not in ("left", "right") for g in goals):
        raise SimError(f"{name}: goals: expected every side 'left' or 'right', got {[g.side for g in goals]}")
    text = ep.instruction
    if not 1 <= len(text) <= max_instruction or any(c not in charset for c in text):
        raise SimError(f"{name}: instruction must be 1 to {max_instruction} characters of {charset!r}, got {text!r}")
    if search:
        pose = ep.start_pose
        try:
            arr = np.asarray(pose, np.float64)
        except (TypeError, ValueError):
            arr = None
        if pose is None or arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise SimError(f"{name}: start_pose: expected (x, y, yaw), 3 finite numbers, got {pose!r}")
    return ep


# --------------------------------------------------------------------------- actions
def check_action(where: str, action: Any, size: int, layout: str, *, flatten: bool = False) -> np.ndarray:
    """``action`` as a float64 vector of ``size`` finite numbers (``layout`` names them, e.g.
    ``"[linear, angular, stop]"``); ``flatten`` accepts any shape with ``size`` elements.

    Shape: returns ``(size,)``.
    """
    try:
        a = np.asarray(action)
        if a.dtype.kind not in "biuf":
            raise TypeError
        a = a.astype(np.float64)
    except (TypeError, ValueError):
        raise SimTypeError(f"{where}: action: expected {size} numbers {layout}, got {type(action).__name__} {action!r}") from None
    if flatten:
        a = a.reshape(-1)
    if a.shape != (size,):
        raise SimError(f"{where}: action: expected shape ({size},) {layout}, got shape {np.shape(action)}")
    if not np.all(np.isfinite(a)):
        raise SimError(f"{where}: action: expected finite numbers, got {a.tolist()}")
    return a
