"""What an agent is and how one is named: the :class:`Agent` protocol, :class:`AgentSpec` and
the table :data:`AGENTS` that :func:`register_agent` fills.

This module imports no agent, so agent modules (:mod:`agents.builtin`, user plugins) register
themselves here without a circle; :mod:`agents.registry` imports the built-in agents and builds
agents by name.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, runtime_checkable

from conceptfusion.errors import AgentError, UnknownNameError
from conceptfusion.names import unknown_name_error

__all__ = [
    "import_module_cleanly", "missing_agent_methods",
    "Agent", "AgentSpec", "Option", "AGENTS", "register_agent", "agent_names", "coerce_kwargs", "check_option", "import_factory",
    "spec_summary",
]


_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1
"""The integers an int :class:`Option` accepts at most, whatever its check says."""


@runtime_checkable
class Agent(Protocol):
    """What the harness needs of an agent."""

    privileged: bool
    """True when the agent reads ground truth (it then receives ``info`` in :meth:`act`)."""

    # Optional: ``reads_scan = False`` says a tabletop agent never reads the observation's orbit
    # scan (``scan_*``), and the runner then renders none (see ``harness.runner.tasks``); an
    # agent without the attribute gets the scan the suite sets. ``reads_images = False`` says a
    # search agent never reads the camera frame (``rgb``, ``depth``, ``K``, ``cam_to_world``) nor
    # the segmentation: the runner then renders none unless the episode is recorded, and its
    # observations are ``base_pose`` and ``goal`` only.

    def reset(self, *, seed: int | None = None) -> None:
        """Forget the last episode; ``seed`` seeds any randomness of the agent."""

    def act(self, observation: Any, info: dict | None = None) -> Any:
        """The next action for this observation (``info`` only for privileged agents)."""


@dataclass(frozen=True)
class Option:
    """One keyword option of an agent: its type, default and the values it accepts.

    ``AgentSpec(kwargs=...)`` takes these, or the short forms ``(type, default)`` and
    ``(type, default, check)``.

    Example::

        from agents import Option

        Option(str, "embedded")                  # --agent-option encoder=... is checked as a string
        Option.at_least(int, 4, 1)              # an integer >= 1, default 4
    """

    type: type
    """``int``, ``float``, ``bool`` or ``str``; command-line strings are converted to it."""
    default: Any
    check: Callable[[Any], bool] | None = None
    """True for an accepted value (after conversion to ``type``); None accepts every value of the
    type. It may also raise ``ValueError`` with its own message (e.g. naming the nearest names)."""
    expected: str = ""
    """What ``check`` accepts, in words (``"an integer >= 1"``), for the error message."""

    @classmethod
    def at_least(cls, kind: type, default: Any, low: float, high: float | None = None) -> "Option":
        """A numeric option with ``low <= value`` (and ``value <= high`` when given)."""
        noun = "an integer" if kind is int else "a number"
        if high is None:
            return cls(kind, default, lambda v: v >= low, f"{noun} >= {low}")
        return cls(kind, default, lambda v: low <= v <= high, f"{noun} in [{low}, {high}]")

    def convert(self, name: str, value: Any) -> Any:
        """``value`` converted to :attr:`type` and checked; ``name`` starts the error messages.
        Whatever :attr:`check` says, a float must be finite and an int must fit in 64 bits (numpy's
        random draws and arrays take no more).

        Raises:
            ValueError: a string that does not convert, or a value ``check`` refuses.
            TypeError: a non-string value of another type.
        """
        out = _convert(name, self.type, value)
        if self.type is float and out != out:
            raise AgentError(f"{name}: expected {self.expected or 'a number'}, got {value!r}")
        if self.check is not None:
            try:
                ok = self.check(out)
            except ValueError as exc:  # a check with its own message (nearest names)
                raise AgentError(f"{name}: {exc}") from exc
            if not ok:
                raise AgentError(f"{name}: expected {self.expected or 'another value'}, got {value!r}")
        if self.type is float and not math.isfinite(out):
            raise AgentError(f"{name}: expected {self.expected or 'a number'}, finite, got {value!r}")
        if self.type is int and not _INT64_MIN <= out <= _INT64_MAX:  # numpy (seeds, random draws) holds no more
            raise AgentError(f"{name}: expected {self.expected or 'an integer'} that fits in 64 bits "
                             f"(at most {_INT64_MAX}), got {value!r}")
        return out


def _as_option(key: str, value: Any) -> Option:
    if isinstance(value, Option):
        return value
    if isinstance(value, tuple) and len(value) in (2, 3) and isinstance(value[0], type):
        return Option(*value)
    raise TypeError(f"AgentSpec option {key!r}: expected an Option, (type, default) or (type, default, check), got {value!r}")


@dataclass(frozen=True)
class AgentSpec:
    """How to build one agent by name: ``cfharness run --agent NAME`` builds it with
    ``factory(**options)``, each option checked against :attr:`kwargs`.

    Example::

        from agents import AgentSpec, register_agent

        register_agent(AgentSpec("my-walker", "mypkg.agents:MyWalker", "object_search", "walks at random",
                                 {"seed": (int, 0)}))
    """

    name: str
    factory: Callable[..., Agent] | str
    """A callable, or an import path ``"module:attribute"`` resolved when first built (so
    heavy agents import nothing until used)."""
    task: str
    """``"tabletop_rearrange"``, ``"object_search"`` or ``"any"``."""
    description: str
    kwargs: dict[str, Option] = field(default_factory=dict)
    """Keyword name -> :class:`Option` accepted by the factory (``(type, default)`` and
    ``(type, default, check)`` tuples are accepted and stored as options)."""
    uses_map: bool = False
    """Builds a ConceptFusion map (map-equipped) or not (map-free baseline)."""
    privileged: bool = False
    """Reads ground truth (oracle policies)."""
    twin_of: str | None = None
    """The map-equipped agent this map-free agent is the matched twin of: the same views,
    exploration, planner and decision rules, differing only in memory (no concept vectors fused
    across views). Reports compare each map agent with its twin first."""

    def __post_init__(self) -> None:
        if self.twin_of is not None and self.uses_map:
            raise ValueError(f"agent {self.name!r}: a matched twin (twin_of={self.twin_of!r}) is map-free; got uses_map=True")
        object.__setattr__(self, "kwargs", {k: _as_option(k, v) for k, v in dict(self.kwargs).items()})

    def defaults(self) -> dict[str, Any]:
        """Keyword name -> default value."""
        return {k: o.default for k, o in self.kwargs.items()}


AGENTS: dict[str, AgentSpec] = {}
"""Registered agents by name."""


def register_agent(spec: AgentSpec) -> AgentSpec:
    """Add a spec; a name can be registered once (``ValueError`` naming it otherwise).

    Example::

        from agents import AgentSpec, Option, make_mapper, register_agent

        register_agent(AgentSpec("my-pusher", lambda encoder="embedded", seed=0: MyPusher(make_mapper(encoder), seed),
                                 "tabletop_rearrange", "my pusher", {"encoder": Option(str, "embedded"),
                                 "seed": Option(int, 0)}, uses_map=True))
        # cfharness run --import mymodule --suite rearrange --agent my-pusher
    """
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
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise TypeError(f"{name}: expected {kind.__name__}, got {type(value).__name__} {value!r}")
    return value


def check_option(spec: AgentSpec, key: str, value: Any) -> Any:
    """``value`` of option ``key`` of an agent, converted to its declared type and checked
    against its :class:`Option` (ranges, names).

    Raises:
        UnknownNameError: the agent has no option ``key`` (naming the nearest one).
        ValueError, TypeError: a value of the wrong type or out of range.
    """
    if key not in spec.kwargs:
        err = unknown_name_error("option", key, spec.kwargs, n=1, cutoff=0.6,
                                 listing=f"options: {', '.join(sorted(spec.kwargs)) or 'none'}")
        raise UnknownNameError(f"agent {spec.name!r}: {err}")
    return spec.kwargs[key].convert(f"agent {spec.name!r} option {key!r}", value)


def coerce_kwargs(spec: AgentSpec, kwargs: dict[str, Any]) -> dict[str, Any]:
    """Check keyword names against the spec, convert values to their declared types and check
    them (see :func:`check_option`)."""
    return {key: check_option(spec, key, value) for key, value in kwargs.items()}


def missing_agent_methods(obj: Any) -> list[str]:
    """Which of an agent's methods, ``reset`` and ``act``, ``obj`` (an agent or its class) lacks
    or holds as something not callable."""
    return [a for a in ("reset", "act") if not callable(getattr(obj, a, None))]


def import_module_cleanly(module: str, where: str, expected: str):
    """``importlib.import_module(module)``, with every way a user module can fail to import (not
    found, its own code raising, its own code calling ``sys.exit``) turned into one
    ``ValueError`` starting with ``where`` and saying it expected ``expected``."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ValueError(f"{where}: cannot import {module!r}: {exc}") from exc
    except SystemExit as exc:
        raise ValueError(f"{where}: expected {expected}, but importing {module!r} called sys.exit({exc.code!r})") from None
    except Exception as exc:  # the module's own code failed
        raise ValueError(f"{where}: expected {expected}, but importing {module!r} raised {type(exc).__name__}: {exc}") from exc


def import_factory(path: str) -> Callable[..., Agent]:
    """The attribute an import path ``"package.module:ClassOrFactory"`` names.

    Raises:
        ValueError: not of that form, the module does not import, or it has no such attribute.
    """
    module, sep, attr = path.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"agent import path: expected 'package.module:ClassOrFactory', got {path!r}")
    mod = import_module_cleanly(module, f"agent import path {path!r}", "a module that imports cleanly")
    try:
        return getattr(mod, attr)
    except AttributeError:
        raise ValueError(f"agent import path {path!r}: module {module!r} has no attribute {attr!r}") from None


def spec_summary(spec: AgentSpec) -> dict[str, Any]:
    """A JSON-friendly description of a spec (for ``--help`` and result records)."""
    d = dataclasses.asdict(spec)
    d["factory"] = spec.factory if isinstance(spec.factory, str) else f"{spec.factory.__module__}:{spec.factory.__qualname__}"
    d["kwargs"] = {k: {"type": o.type.__name__, "default": o.default} for k, o in spec.kwargs.items()}
    return d
