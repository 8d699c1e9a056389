"""Training, export, evaluation and score-floor calibration of the embedded image tower
that ships in :mod:`conceptfusion.perception.image_tower`: labelled views rendered from the
simulator (``views``), crops (``data``), the LiT-style loop (``training``), the command
``python -m tower_training.train`` and ``python -m tower_training.evaluate --calibrate-floor``.

May import: :mod:`sim_envs`, :mod:`conceptfusion` and :mod:`planners`; the core never imports it.
"""
