"""Scenes and episodes as data: the declarative scene formats (tabletop v1, household v2),
the seeded generators, floor plans, the ground-truth scene graph, the standard camera
trajectories (``trajectories``), and episode files (JSON Lines) for rearrangement and object search.

May import: :mod:`sim_envs.assets`, :mod:`planners`, and :mod:`conceptfusion` base modules.
"""
