"""Training, export, evaluation and score-floor calibration of the embedded image tower
that ships in :mod:`conceptfusion.perception.image_tower`: labelled views rendered from the
simulator (``views``), crops (``data``), the LiT-style loop (``training``), the command
``python -m tower_training.train`` and ``python -m tower_training.evaluate --calibrate-floor``.

v2 (the object library, ``--world v2``): table arrangements of library instances
(``library_views``), captions per instance (``captions``), the split-aware crop sets
(``world_v2``), the multi-caption training command (``train_v2``) and its metrics
(``evaluate_v2``); the v2 score floor is ``evaluate.calibrate_score_floor_v2``.

May import: :mod:`sim_envs`, :mod:`conceptfusion` and :mod:`planners`; the core never imports it.
"""
