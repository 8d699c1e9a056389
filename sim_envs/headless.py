"""Headless OpenGL selection for MuJoCo, done once before MuJoCo is imported.

``MUJOCO_GL=egl`` works on machines without a display and without extra packages (Mesa's
software rasteriser); ``osmesa`` needs the Debian package ``libosmesa6``. A value the user
set is respected.
"""

from __future__ import annotations

import os

__all__ = ["configure_headless_gl"]


def configure_headless_gl() -> str:
    """Set ``MUJOCO_GL`` (default ``egl``) and ``PYOPENGL_PLATFORM`` to match; returns the backend."""
    backend = os.environ.setdefault("MUJOCO_GL", "egl")
    if backend in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    return backend


configure_headless_gl()
