"""Agents: ``reset()`` / ``act(observation) -> action``, the agent registry, the ConceptFusion
mapper agents use (``concept_map``), map-equipped agents (pusher, navigator with frontier
exploration), map-free baselines, privileged oracle agents, and the spatial-question parsers
(``agents.spatial``).

The names a user needs are importable from here (loaded on first use, so ``import agents``
imports nothing)::

    from agents import AgentSpec, Option, make_agent, make_mapper, register_agent

May import: :mod:`conceptfusion` and :mod:`planners`; never :mod:`sim_envs` or :mod:`harness`
(agents see only observations, and ``info`` when marked privileged).
"""

from __future__ import annotations

__all__ = ["AgentSpec", "Option", "make_agent", "make_mapper", "register_agent"]


def __getattr__(name: str):
    """A public name of :data:`__all__`, imported from its module on first use (the registry
    first, so the built-in agents are registered before a user's)."""
    if name in ("AgentSpec", "make_agent", "register_agent"):
        from agents import registry as module
    elif name == "Option":
        from agents import spec as module
    elif name == "make_mapper":
        from agents import builtin as module
    else:
        raise AttributeError(f"module 'agents' has no attribute {name!r} (public names: {', '.join(__all__)})")
    value = getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
