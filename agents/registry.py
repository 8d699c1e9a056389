"""Agents by name: one spec per agent, so the harness can run any agent from a string.

Every agent follows the same small protocol (:class:`Agent`): ``reset(seed=...)`` at the start
of an episode and ``act(observation, info)`` once per step, returning an action of the
environment's action space. ``info`` is the environment's info dict and is passed **only to
privileged agents** (``privileged = True``); everyone else gets ``None``, so ground truth cannot
leak into a non-privileged agent by accident.

An :class:`AgentSpec` names a factory and its keyword arguments with their types and defaults;
:func:`make_agent` checks and converts keyword values (strings from a command line become
ints, floats and bools) before calling the factory. User agents are registered the same way,
or loaded from an import path ``"package.module:ClassOrFactory"`` (see :func:`make_agent`).
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, runtime_checkable

__all__ = ["Agent", "AgentSpec", "AGENTS", "register_agent", "make_agent", "agent_names", "coerce_kwargs"]


@runtime_checkable
class Agent(Protocol):
    """What the harness needs of an agent."""

    privileged: bool
    """True when the agent reads ground truth (it then receives ``info`` in :meth:`act`)."""

    def reset(self, *, seed: int | None = None) -> None:
        """Forget the last episode; ``seed`` seeds any randomness of the agent."""

    def act(self, observation: Any, info: dict | None = None) -> Any:
        """The next action for this observation (``info`` only for privileged agents)."""


@dataclass(frozen=True)
class AgentSpec:
    """How to build one agent by name."""

    name: str
    factory: Callable[..., Agent] | str
    """A callable, or an import path ``"module:attribute"`` resolved when first built (so
    heavy agents import nothing until used)."""
    task: str
    """``"tabletop_rearrange"``, ``"object_search"`` or ``"any"``."""
    description: str
    kwargs: dict[str, tuple[type, Any]] = field(default_factory=dict)
    """Keyword name -> (type, default) accepted by the factory."""
    uses_map: bool = False
    """Builds a ConceptFusion map (map-equipped) or not (map-free baseline)."""
    privileged: bool = False
    """Reads ground truth (oracle policies)."""


AGENTS: dict[str, AgentSpec] = {}
"""Registered agents by name."""


def register_agent(spec: AgentSpec) -> AgentSpec:
    """Add a spec; a name can be registered once."""
    if spec.name in AGENTS:
        raise ValueError(f"agent {spec.name!r} is already registered")
    AGENTS[spec.name] = spec
    return spec


def agent_names(task: str | None = None) -> list[str]:
    """Registered names, optionally only those that solve ``task``."""
    return sorted(n for n, s in AGENTS.items() if task is None or s.task in (task, "any"))


def _convert(name: str, kind: type, value: Any) -> Any:
    if isinstance(value, str) and kind is not str:
        text = value.strip()
        if kind is bool:
            low = text.lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError(f"{name}: expected a boolean (true/false), got {value!r}")
        try:
            return kind(text)
        except ValueError:
            raise ValueError(f"{name}: expected {kind.__name__}, got {value!r}") from None
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if not isinstance(value, kind):
        raise TypeError(f"{name}: expected {kind.__name__}, got {type(value).__name__} {value!r}")
    return value


def coerce_kwargs(spec: AgentSpec, kwargs: dict[str, Any]) -> dict[str, Any]:
    """Check keyword names against the spec and convert values to their declared types."""
    out = {}
    for key, value in kwargs.items():
        if key not in spec.kwargs:
            near = difflib.get_close_matches(key, spec.kwargs, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ValueError(f"agent {spec.name!r}: unknown option {key!r}{hint} (options: {sorted(spec.kwargs) or 'none'})")
        out[key] = _convert(f"agent {spec.name!r} option {key!r}", spec.kwargs[key][0], value)
    return out


def _resolve(path: str) -> Callable[..., Agent]:
    module, sep, attr = path.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"agent import path: expected 'package.module:ClassOrFactory', got {path!r}")
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise ValueError(f"agent import path {path!r}: cannot import {module!r}: {exc}") from exc
    try:
        return getattr(mod, attr)
    except AttributeError:
        raise ValueError(f"agent import path {path!r}: module {module!r} has no attribute {attr!r}") from None


def make_agent(name: str, **kwargs: Any) -> Agent:
    """Build a registered agent, or a user agent from ``"package.module:Class"``.

    Unknown names raise ``ValueError`` naming the nearest registered ones. The built object
    must have ``reset``, ``act`` and ``privileged``.
    """
    _load_builtin()
    if name in AGENTS:
        spec = AGENTS[name]
        factory = _resolve(spec.factory) if isinstance(spec.factory, str) else spec.factory
        agent = factory(**{k: d for k, (_, d) in spec.kwargs.items()} | coerce_kwargs(spec, kwargs))
    elif ":" in name:
        agent = _resolve(name)(**kwargs)
    else:
        near = difflib.get_close_matches(name, AGENTS, n=3, cutoff=0.4)
        hint = f"; did you mean {', '.join(repr(n) for n in near)}?" if near else ""
        raise ValueError(f"unknown agent {name!r}{hint} (registered: {', '.join(agent_names())}; or give 'module:Class')")
    missing = [a for a in ("reset", "act") if not callable(getattr(agent, a, None))]
    if missing or not hasattr(agent, "privileged"):
        raise TypeError(f"agent {name!r}: expected reset(), act() and a 'privileged' attribute; missing {missing or ['privileged']}")
    return agent


_BUILTIN_LOADED = False


def _load_builtin() -> None:
    """Import the modules that register the built-in agents (once)."""
    global _BUILTIN_LOADED
    if not _BUILTIN_LOADED:
        _BUILTIN_LOADED = True
        importlib.import_module("agents.builtin")


def spec_summary(spec: AgentSpec) -> dict[str, Any]:
    """A JSON-friendly description of a spec (for ``--help`` and result records)."""
    d = dataclasses.asdict(spec)
    d["factory"] = spec.factory if isinstance(spec.factory, str) else f"{spec.factory.__module__}:{spec.factory.__qualname__}"
    d["kwargs"] = {k: {"type": t.__name__, "default": v} for k, (t, v) in spec.kwargs.items()}
    return d
