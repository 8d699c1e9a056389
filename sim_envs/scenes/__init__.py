"""Scenes and episodes as data: the declarative scene formats (tabletop v1, household v2),
the seeded generators, floor plans, the ground-truth scene graph, the standard camera
trajectories (``trajectories``), and episode files (JSON Lines) for rearrangement and object search.
v2 data draws from the object library: ``descriptions`` (how a goal is named: name, synonym,
attribute, function, parent), ``gen_tabletop_v2`` and ``tabletop_v2_episodes`` (tabletops and
rearrangement episodes inside the Panda's reach, checked by an injected reach test).

May import: :mod:`sim_envs.assets`, :mod:`planners`, and :mod:`conceptfusion` base modules.
"""
