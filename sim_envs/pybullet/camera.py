"""RGB-D + instance segmentation cameras for PyBullet, headless.

Renderers: PyBullet's software "tiny" renderer, or OpenGL through the EGL plugin (on a machine
without a GPU, Mesa's software rasteriser; about twice as fast). ``renderer="auto"`` uses EGL
when the plugin is (or can be) loaded and the tiny renderer otherwise.

The EGL plugin only draws bodies created after it was loaded into the client, and once loaded it
serves every camera image of that client: call :func:`load_egl_plugin` before building the scene.

The two renderers place pixel samples differently. EGL samples pixel centres, so the principal
point is ``((W - 1) / 2, (H - 1) / 2)``; the tiny renderer's is ``(W / 2, H / 2 - 1)`` (measured:
with it, back-projected depth of a tilted plane lands exactly on the plane, with the centre
convention up to 1 cm off at grazing views). ``K`` follows the renderer in use.

Outputs follow the :mod:`conceptfusion` conventions: OpenCV camera frame, 4x4 float64
camera-to-world pose, metric depth along the optical axis (``inf`` where nothing is hit).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys

import numpy as np

from conceptfusion.cameras import intrinsics_from_fovy
from conceptfusion.errors import ShapeError
from conceptfusion.frames import RGBDFrame
from sim_envs.cameras import opengl_depth_to_metric, opengl_to_opencv_pose

__all__ = ["PyBulletRGBDCamera", "load_egl_plugin", "forget_client", "disconnect_quietly", "native_stdout_quiet", "pybullet_camera_pose", "RENDERERS"]

RENDERERS = ("auto", "tiny", "egl")
"""Renderer names :class:`PyBulletRGBDCamera` accepts."""

_log = logging.getLogger(__name__)
_EGL_PLUGINS: dict[int, int] = {}
_WARM: set[int] = set()  # clients whose first images were rendered (PyBulletRGBDCamera.warm_up)
_RENDERED: dict[int, int] = {}  # client -> images rendered (the EGL plugin prints its GL vendor on the first two)
_EGL_CONTEXTS: dict[int, tuple] = {}  # client -> (display, draw, read, context) its plugin made current


class _Egl:
    """The few EGL calls that keep the plugin's context current (ctypes on ``libEGL.so.1``).

    The plugin makes its GL context current once, when it loads, and draws into whatever context
    is current at each image. Anything else that renders with EGL in the thread (a MuJoCo camera)
    makes its own context current, and the plugin then draws nothing (every pixel empty). The
    camera therefore puts the plugin's context back before each image and restores the previous
    one after it.
    """

    _lib = None

    @classmethod
    def lib(cls):
        if cls._lib is None:
            import ctypes

            lib = ctypes.CDLL("libEGL.so.1")
            for name in ("eglGetCurrentDisplay", "eglGetCurrentContext", "eglGetCurrentSurface"):
                getattr(lib, name).restype = ctypes.c_void_p
            lib.eglGetCurrentSurface.argtypes = [ctypes.c_int]
            lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
            lib.eglMakeCurrent.restype = ctypes.c_uint
            cls._lib = lib
        return cls._lib

    @classmethod
    def current(cls) -> tuple:
        lib = cls.lib()
        return (lib.eglGetCurrentDisplay(), lib.eglGetCurrentSurface(0x3059), lib.eglGetCurrentSurface(0x305A), lib.eglGetCurrentContext())

    @classmethod
    def make_current(cls, state: tuple) -> None:
        if state[0] is None:  # nothing was current: release
            lib = cls.lib()
            display = lib.eglGetCurrentDisplay()
            if display:
                lib.eglMakeCurrent(display, None, None, None)
            return
        if not cls.lib().eglMakeCurrent(*state):
            raise RuntimeError("PyBullet EGL renderer: eglMakeCurrent failed to restore a GL context")


def pybullet_camera_pose(view_matrix_16) -> np.ndarray:
    """OpenCV camera-to-world pose from a PyBullet view matrix (16 floats, column-major).

    Shape:
        (16,) -> (4, 4) float64.
    """
    view = np.asarray(view_matrix_16, dtype=np.float64)
    if view.size != 16:
        raise ShapeError(f"view_matrix_16: expected 16 values, got {view.size}")
    V = np.reshape(view, (4, 4), order="F")
    return opengl_to_opencv_pose(np.linalg.inv(V))


@contextlib.contextmanager
def native_stdout_quiet():
    """Within the block, what native code writes to the process's standard output (file
    descriptor 1) goes nowhere: PyBullet's EGL plugin prints its GL vendor strings on loading and
    "Destroy EGL OpenGL window." on unloading, which would interleave with a run's output. Python's
    own ``sys.stdout`` is flushed first, so nothing of it is lost."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):  # no usable fd 1 (an embedding host): leave it alone
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        _flush_c_stdio()  # what the native code printf-ed sits in C's buffer: empty it into /dev/null
        os.dup2(saved, 1)
        os.close(saved)


def _flush_c_stdio() -> None:
    """``fflush(NULL)`` of the C library (best effort: a platform without it keeps its buffer)."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):
        pass


def disconnect_quietly(client: int) -> None:
    """``p.disconnect(client)`` without the EGL plugin's farewell on standard output, and
    :func:`forget_client` (PyBullet reuses client ids)."""
    import pybullet as p

    try:
        with native_stdout_quiet():
            p.disconnect(physicsClientId=client)
    finally:
        forget_client(client)


def load_egl_plugin(client: int) -> bool:
    """Load PyBullet's EGL renderer plugin into ``client`` once; True when it loaded."""
    if client in _EGL_PLUGINS:
        return _EGL_PLUGINS[client] >= 0
    import importlib.util

    import pybullet as p

    plugin = -1
    spec = importlib.util.find_spec("eglRenderer")
    if spec is not None and spec.origin:
        with native_stdout_quiet():  # the plugin prints its GL vendor strings
            plugin = p.loadPlugin(spec.origin, "_eglRendererPlugin", physicsClientId=client)
    if plugin < 0:
        _log.info("PyBullet EGL renderer plugin did not load; using the tiny renderer")
    else:
        try:
            _EGL_CONTEXTS[client] = _Egl.current()
        except OSError:  # no libEGL to call: the plugin's context stays as it is
            pass
    _EGL_PLUGINS[client] = plugin
    return plugin >= 0


def forget_client(client: int) -> None:
    """Drop what is remembered about ``client``'s plugin; call it when disconnecting the client
    (PyBullet reuses client ids)."""
    _EGL_PLUGINS.pop(client, None)
    _EGL_CONTEXTS.pop(client, None)
    _WARM.discard(client)
    _RENDERED.pop(client, None)


class PyBulletRGBDCamera:
    """A free camera rendering colour, depth and instance segmentation of a PyBullet client.

    Args:
        client: the physics client id.
        width, height: image size in pixels.
        fovy_deg: vertical field of view.
        body_object: per body id, the object index its pixels report (-1: none); bodies past
            its end report -1.
        renderer: "auto", "tiny" or "egl" ("egl" raises when the plugin does not load).
        near, far: clipping planes in metres; depth at the far plane is ``inf``.
    """

    def __init__(
        self,
        client: int,
        width: int,
        height: int,
        *,
        fovy_deg: float = 60.0,
        body_object: np.ndarray | None = None,
        renderer: str = "auto",
        near: float = 0.01,
        far: float = 20.0,
    ) -> None:
        import pybullet as p

        if renderer not in RENDERERS:
            raise ValueError(f"renderer: expected one of {RENDERERS}, got {renderer!r}")
        if width <= 0 or height <= 0:
            raise ValueError(f"width, height: expected positive sizes, got {width}x{height}")
        if not 0 < near < far:
            raise ValueError(f"near, far: expected 0 < near < far, got {near}, {far}")
        self.client = int(client)
        self.width, self.height = int(width), int(height)
        self.fovy_deg = float(fovy_deg)
        self.near, self.far = float(near), float(far)
        loaded = _EGL_PLUGINS.get(self.client, -1) >= 0
        if renderer == "tiny" and loaded:
            raise RuntimeError("renderer='tiny': this client has the EGL plugin loaded, which then renders every image; use 'egl' or 'auto'")
        if renderer != "tiny" and not loaded:
            if p.getNumBodies(physicsClientId=self.client) > 0:
                if renderer == "egl":
                    raise RuntimeError(
                        "renderer='egl': the EGL plugin draws only bodies created after it loads; "
                        "call load_egl_plugin(client) before building the scene"
                    )
            else:
                loaded = load_egl_plugin(self.client)
        if renderer == "egl" and not loaded:
            raise RuntimeError("renderer='egl': PyBullet's EGL plugin (eglRenderer) did not load; use 'tiny' or 'auto'")
        use_egl = renderer != "tiny" and loaded
        self.renderer = "egl" if use_egl else "tiny"
        self.K = intrinsics_from_fovy(self.fovy_deg, self.width, self.height)
        if not use_egl:
            self.K[0, 2], self.K[1, 2] = self.width / 2.0, self.height / 2.0 - 1.0
        self._gl_flag = p.ER_BULLET_HARDWARE_OPENGL if use_egl else p.ER_TINY_RENDERER
        self._proj = p.computeProjectionMatrixFOV(self.fovy_deg, self.width / self.height, self.near, self.far)
        self.set_body_object(body_object)
        self._view = None

    def set_body_object(self, body_object: np.ndarray | None) -> None:
        """Replace the body-id -> object-index lookup."""
        lut = np.full(1, -1, np.int32) if body_object is None else np.asarray(body_object, np.int32).reshape(-1)
        self._lut = np.concatenate([lut, [-1]]).astype(np.int32)  # last entry: out of range, background

    def set_pose(self, eye, target) -> None:
        """Place the camera at ``eye`` looking at ``target`` (world metres, z up)."""
        import pybullet as p

        eye = np.asarray(eye, np.float64).reshape(-1)
        target = np.asarray(target, np.float64).reshape(-1)
        if eye.shape != (3,) or target.shape != (3,):
            raise ValueError(f"eye, target: expected 3 numbers each, got shapes {eye.shape}, {target.shape}")
        fwd = target - eye
        n = np.linalg.norm(fwd)
        if n < 1e-9:
            raise ValueError("eye and target coincide")
        up = np.array([0.0, 0.0, 1.0])
        if np.linalg.norm(np.cross(fwd / n, up)) < 1e-6:  # looking straight up or down
            up = np.array([0.0, 1.0, 0.0])
        self._view = p.computeViewMatrix(eye.tolist(), target.tolist(), up.tolist())

    def render(self, *, segmentation: bool = True) -> RGBDFrame:
        """Render the current state from the current pose.

        With ``segmentation=False`` the segmentation is all -1 (a little faster).

        Shape:
            see :class:`~conceptfusion.frames.RGBDFrame`; ``segmentation`` (H, W) int32.
        """
        import pybullet as p

        if self._view is None:
            raise RuntimeError("render: call set_pose(eye, target) first")
        flags = 0 if segmentation else p.ER_NO_SEGMENTATION_MASK
        own = _EGL_CONTEXTS.get(self.client) if self.renderer == "egl" else None
        previous = _Egl.current() if own is not None else None
        if own is not None and previous != own:
            _Egl.make_current(own)
        first = self.renderer == "egl" and _RENDERED.get(self.client, 0) < 2
        try:
            with native_stdout_quiet() if first else contextlib.nullcontext():  # the plugin's GL vendor strings
                _, _, rgba, zbuf, seg = p.getCameraImage(
                    self.width, self.height, self._view, self._proj, renderer=self._gl_flag, flags=flags,
                    physicsClientId=self.client,
                )
            _RENDERED[self.client] = _RENDERED.get(self.client, 0) + 1
        finally:
            if own is not None and previous != own:
                _Egl.make_current(previous)
        rgb = np.asarray(rgba, np.uint8).reshape(self.height, self.width, 4)[..., :3].copy()
        zb = np.asarray(zbuf, np.float64).reshape(self.height, self.width)
        depth = opengl_depth_to_metric(zb, self.near, self.far)
        depth[zb >= 1.0 - 1e-7] = np.inf
        if segmentation:
            ids = np.asarray(seg, np.int64).reshape(self.height, self.width)
            body = np.where(ids < 0, -1, ids & 0xFFFFFF)
            body = np.where((body < 0) | (body >= len(self._lut) - 1), len(self._lut) - 1, body)
            labels = self._lut[body]
        else:
            labels = np.full((self.height, self.width), -1, np.int32)
        return RGBDFrame(rgb=rgb, depth=depth, K=self.K.copy(), cam_to_world=pybullet_camera_pose(self._view), segmentation=labels)

    def warm_up(self) -> None:
        """Render and drop the client's first images. The EGL plugin shades the first two images
        of a client differently from every later one (measured: colours up to 33 levels apart,
        depth and labels the same), so without this a seeded reset would not repeat its first
        observation. Keeps the current pose."""
        import pybullet as p

        if self.renderer != "egl" or self.client in _WARM:
            return
        view = self._view
        self._view = p.computeViewMatrix([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0])
        try:
            for _ in range(2):
                self.render(segmentation=False)
        finally:
            self._view = view
        _WARM.add(self.client)

    def close(self) -> None:
        """Nothing to release (the client owns the renderer); present for symmetry."""
