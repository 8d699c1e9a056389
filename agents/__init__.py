"""Agents: ``reset()`` / ``act(observation) -> action``, the agent registry, the ConceptFusion
mapper agents use (``concept_map``), map-equipped agents (pusher, navigator with frontier
exploration), map-free baselines, privileged oracle agents, and the spatial-question parsers
(``agents.spatial``).

May import: :mod:`conceptfusion` and :mod:`planners`; never :mod:`sim_envs` or :mod:`harness`
(agents see only observations, and ``info`` when marked privileged).
"""
