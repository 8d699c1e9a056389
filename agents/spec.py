"""What an agent is and how one is named: the :class:`Agent` protocol, :class:`AgentSpec` and
the table :data:`AGENTS` that :func:`register_agent` fills.

This module imports no agent, so agent modules (:mod:`agents.builtin`, user plugins) register
themselves here without a circle; :mod:`agents.registry` imports the built-in agents and builds
agents by name.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, runtime_checkable

from conceptfusion.errors import UnknownNameError
from conceptfusion.names import unknown_name_error

__all__ = ["Agent", "AgentSpec", "AGENTS", "register_agent", "agent_names", "coerce_kwargs", "import_factory", "spec_summary"]


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
            err = unknown_name_error("option", key, spec.kwargs, n=1, cutoff=0.6,
                                     listing=f"options: {', '.join(sorted(spec.kwargs)) or 'none'}")
            raise UnknownNameError(f"agent {spec.name!r}: {err}")
        out[key] = _convert(f"agent {spec.name!r} option {key!r}", spec.kwargs[key][0], value)
    return out


def import_factory(path: str) -> Callable[..., Agent]:
    """The attribute an import path ``"package.module:ClassOrFactory"`` names.

    Raises:
        ValueError: not of that form, the module does not import, or it has no such attribute.
    """
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


def spec_summary(spec: AgentSpec) -> dict[str, Any]:
    """A JSON-friendly description of a spec (for ``--help`` and result records)."""
    d = dataclasses.asdict(spec)
    d["factory"] = spec.factory if isinstance(spec.factory, str) else f"{spec.factory.__module__}:{spec.factory.__qualname__}"
    d["kwargs"] = {k: {"type": t.__name__, "default": v} for k, (t, v) in spec.kwargs.items()}
    return d
