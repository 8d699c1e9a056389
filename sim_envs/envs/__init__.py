"""The Gymnasium environments (``cf/SceneScan-v0``, ``cf/TabletopRearrange-v0``,
``cf/ObjectSearch-v0``), their pure success functions, the tabletop backend protocol, and what
they share about their camera (``rendering``: frame observation spaces, ``render``/``close``).

May import: the rest of :mod:`sim_envs`, :mod:`planners`, :mod:`conceptfusion` base modules.
"""
