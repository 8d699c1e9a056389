"""What the environments share about their camera: the observation spaces of a posed RGB-D
frame, ``render()`` and ``close()``.

Every observation holds one :class:`~conceptfusion.frames.RGBDFrame` as ``rgb``, ``depth``,
``K`` and ``cam_to_world`` (:meth:`RGBDFrame.observation`; its labels go to ``info`` only).
Every environment of :mod:`sim_envs.envs` renders the same way: ``render_mode`` is ``None`` or
``"rgb_array"``, and ``render()`` returns the colour image of the frame the last observation
came from (no extra rendering). ``close()`` releases the one resource that renders (a camera or
the whole simulation) and may be called more than once.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from conceptfusion.errors import SimError
from conceptfusion.frames import RGBDFrame
from conceptfusion.names import did_you_mean

__all__ = ["RENDER_MODES", "check_render_mode", "frame_spaces", "LastFrameRendering"]

RENDER_MODES = ("rgb_array",)
"""The render modes every environment supports (besides ``None``)."""


def frame_spaces(height: int, width: int) -> dict[str, spaces.Box]:
    """Observation spaces of one posed frame: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32
    metres (``inf``: nothing hit), ``K`` (3, 3) and ``cam_to_world`` (4, 4) float64."""
    return {
        "rgb": spaces.Box(0, 255, (height, width, 3), np.uint8),
        "depth": spaces.Box(0.0, np.inf, (height, width), np.float32),
        "K": spaces.Box(-np.inf, np.inf, (3, 3), np.float64),
        "cam_to_world": spaces.Box(-np.inf, np.inf, (4, 4), np.float64),
    }


def check_render_mode(render_mode: str | None) -> str | None:
    """``render_mode`` when it is ``None`` or one of :data:`RENDER_MODES`; otherwise
    :class:`~conceptfusion.errors.SimError` (a ``ValueError``) naming the nearest mode."""
    if render_mode is not None and not (isinstance(render_mode, str) and render_mode in RENDER_MODES):
        hint = did_you_mean(render_mode, RENDER_MODES, n=1) if isinstance(render_mode, str) else ""
        raise SimError(f"render_mode: expected None or 'rgb_array', got {render_mode!r}{hint}")
    return render_mode


class LastFrameRendering:
    """Mixin (put it before ``gym.Env``) giving an environment its ``render()`` and ``close()``.

    The environment sets ``render_mode`` (checked with :func:`check_render_mode`), stores the
    frame of each observation in ``_last_frame``, and names in ``_renderer_attr`` the attribute
    that holds what ``close()`` releases (anything with a ``close()`` method).
    """

    render_mode: str | None = None
    _last_frame: RGBDFrame | None = None
    _renderer_attr: str = "_camera"

    def render(self) -> np.ndarray | None:
        """The last observation's colour image, (H, W, 3) uint8, in ``"rgb_array"`` mode; else ``None``."""
        if self.render_mode == "rgb_array" and self._last_frame is not None:
            return self._last_frame.rgb
        return None

    def close(self) -> None:
        """Release the camera or simulation (idempotent)."""
        renderer = getattr(self, self._renderer_attr, None)
        if renderer is not None:
            renderer.close()
            setattr(self, self._renderer_attr, None)
        super().close()  # type: ignore[misc]  (the next close() in the MRO, e.g. gym.Env's)
