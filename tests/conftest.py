"""Shared pytest set-up: headless rendering for every test that touches a simulator."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
