"""The map suites: scanning shipped scenes, fusing maps, and scoring queries (``query``),
pixel-feature ablations (``ablation``) and spatial questions (``spatial``) against simulator
ground truth; ``suites`` names each suite's cases and how one is scored
(:mod:`harness.runner.map_jobs` turns them into jobs).

May import: :mod:`agents`, :mod:`sim_envs`, :mod:`conceptfusion`.
"""
