"""Shared pytest set-up: headless rendering for every test that touches a simulator."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def pytest_collection_modifyitems(config, items):
    """The regression gate (``gate`` tests: hundreds of episodes on worker processes) runs last.

    With ``-n`` (pytest-xdist, the default in ``pyproject.toml``) the load scheduler hands out the
    quick tests first and the gate tests as workers free up, so each gate test overlaps the others
    instead of queueing behind one long test on one worker."""
    gate = [item for item in items if item.get_closest_marker("gate") is not None]
    if gate:
        rest = [item for item in items if item.get_closest_marker("gate") is None]
        items[:] = rest + gate
