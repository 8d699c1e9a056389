"""What the process backend's fork server imports once, so that its workers start warm.

The process backend forks its workers from a fork server (:mod:`harness.runner.process_pool`), a
fresh interpreter that imports this module and nothing of the parent's state. Each worker then
starts with these modules already imported instead of importing them itself: torch, the
sentence-transformers stack of the MiniLM text tower, onnxruntime, MuJoCo and the harness's
job modules, about 5 s of imports per worker on a 2-core machine. Nothing here starts a
thread, opens a GL context or loads model weights (a forked child must not inherit those).

A module that is missing (an optional extra not installed) or fails to import is skipped; the
worker that needs it imports it itself and reports the error there.
"""

from __future__ import annotations

import importlib

PRELOADED = (
    "numpy",
    "scipy.stats",
    "torch",
    "onnxruntime",
    "sentence_transformers",
    "sim_envs.headless",
    "mujoco",
    "harness.runner.tasks",
    "harness.runner.map_jobs",
    "agents.builtin",
    "conceptfusion.perception.featurizer",
)
"""Modules imported in the fork server, in this order (``sim_envs.headless`` picks the GL
backend before ``mujoco`` loads)."""

for _name in PRELOADED:
    try:
        importlib.import_module(_name)
    except Exception:  # noqa: BLE001 - a worker that needs it imports it and reports the error
        pass
