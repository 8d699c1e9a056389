"""Shipped scene and episode data (``household/``, ``tabletop/``, ``tabletop-v2/`` ...) and the
scripts that regenerate them from the seeded generators in :mod:`sim_envs.scenes`.
"""
