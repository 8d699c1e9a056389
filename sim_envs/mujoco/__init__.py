"""MuJoCo backend: a scene file to an MJCF model (``scene``, ``household``, ``tabletop``),
headless RGB-D + segmentation cameras and the one scan function (``camera``, ``scan``).

May import: :mod:`sim_envs.scenes`, :mod:`sim_envs.assets`, :mod:`conceptfusion` base modules.
"""
