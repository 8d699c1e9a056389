"""Agents by name: one spec per agent, so the harness can run any agent from a string.

Every agent follows the same small protocol (:class:`~agents.spec.Agent`): ``reset(seed=...)``
at the start of an episode and ``act(observation, info)`` once per step, returning an action of
the environment's action space. ``info`` is the environment's info dict and is passed **only to
privileged agents** (``privileged = True``); everyone else gets ``None``, so ground truth cannot
leak into a non-privileged agent by accident.

An :class:`~agents.spec.AgentSpec` names a factory and its keyword arguments with their types and
defaults; :func:`make_agent` checks and converts keyword values (strings from a command line
become ints, floats and bools) before calling the factory. User agents are registered the same
way (:func:`~agents.spec.register_agent`), or loaded from an import path
``"package.module:ClassOrFactory"`` (see :func:`make_agent`).

Importing this module registers the built-in agents (:mod:`agents.builtin`), so
:data:`AGENTS` is complete on import.
"""

from __future__ import annotations

from typing import Any, Callable

import agents.builtin  # noqa: F401  (registers the built-in agents)
from agents.spec import AGENTS, Agent, AgentSpec, agent_names, coerce_kwargs, import_factory, missing_agent_methods, register_agent, spec_summary
from conceptfusion.names import unknown_name_error

__all__ = [
    "Agent", "AgentSpec", "AGENTS", "register_agent", "make_agent", "agent_names", "coerce_kwargs", "resolve_agent",
    "spec_summary",
]


def _unknown_agent(name: str) -> Exception:
    return unknown_name_error("agent", name, AGENTS, listing=f"registered: {', '.join(agent_names())}; or give 'module:Class'")


def resolve_agent(name: str) -> Callable[..., Agent]:
    """The factory of a registered agent, or of a user agent given as ``"package.module:Class"``.

    Raises:
        UnknownNameError: neither a registered name nor an import path (naming the nearest names).
        ValueError: an import path that does not import.
    """
    if name in AGENTS:
        factory = AGENTS[name].factory
        return import_factory(factory) if isinstance(factory, str) else factory
    if ":" in name:
        return import_factory(name)
    raise _unknown_agent(name)


def make_agent(name: str, **kwargs: Any) -> Agent:
    """Build a registered agent, or a user agent from ``"package.module:Class"``.

    Unknown names raise :class:`~conceptfusion.errors.UnknownNameError` (a ``ValueError``) naming
    the nearest registered ones. The built object must have ``reset``, ``act`` and ``privileged``.

    Example::

        from agents import make_agent

        agent = make_agent("map-pusher", encoder="color")   # options as cfharness list shows them
        agent.reset(seed=0)
    """
    factory = resolve_agent(name)
    if name in AGENTS:
        spec = AGENTS[name]
        agent = factory(**spec.defaults() | coerce_kwargs(spec, kwargs))
    else:
        agent = factory(**kwargs)
    missing = missing_agent_methods(agent)
    if missing or not hasattr(agent, "privileged"):
        raise TypeError(f"agent {name!r}: expected reset(), act() and a 'privileged' attribute; missing {missing or ['privileged']}")
    return agent
