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

from conceptfusion.names import lazy_exports

__all__ = ["AgentSpec", "Option", "make_agent", "make_mapper", "register_agent"]


__getattr__, __dir__ = lazy_exports(__name__, {
    "AgentSpec": "agents.registry", "make_agent": "agents.registry", "register_agent": "agents.registry",
    "Option": "agents.spec", "make_mapper": "agents.builtin",
})
"""Each public name of :data:`__all__` is imported from its module on first use (the registry's
from the registry, so the built-in agents are registered before a user's)."""
