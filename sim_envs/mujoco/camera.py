"""RGB-D + instance segmentation cameras for MuJoCo, headless and fast.

One frame takes two render passes: a colour pass, and a flat-colour segmentation pass whose
depth buffer gives metric depth at the same time. Shadows, reflections and multisampling are
off by default (they cost 10x in colour rendering on a software rasteriser and add nothing
a mapping pipeline needs). Create one camera per process; never share one across processes.

Outputs are :class:`conceptfusion.frames.RGBDFrame` in the :mod:`conceptfusion` conventions:
OpenCV camera frame, 4x4 float64 camera-to-world pose, metric depth along the optical axis
(``inf`` where nothing is hit), ``segmentation`` (H, W) int32 object index (-1: background or
unnamed geometry).

Under EGL (the headless default) every camera of a thread renders in one GL context that lives as
long as the thread: EGL contexts are surfaceless here (MuJoCo draws into each camera's own
offscreen framebuffer), and the first renderer made in a fresh context costs about 55 ms (the
software rasteriser sets itself up per context) against 8 ms in a used one. A camera per episode
(a new scene per episode) paid that every time. Other GL backends keep a context per camera.
"""

from __future__ import annotations

import os
import threading

import numpy as np

from sim_envs import headless  # noqa: F401  (selects the GL backend before mujoco loads)

import mujoco  # noqa: E402

from conceptfusion.cameras import intrinsics_from_fovy  # noqa: E402
from conceptfusion.errors import ShapeError  # noqa: E402
from conceptfusion.frames import RGBDFrame  # noqa: E402
from sim_envs.cameras import opengl_to_opencv_pose  # noqa: E402

__all__ = ["MujocoRGBDCamera", "look_at_gl", "mujoco_camera_pose"]


def mujoco_camera_pose(cam_xpos_3, cam_xmat_9) -> np.ndarray:
    """OpenCV camera-to-world pose of a MuJoCo camera from ``data.cam_xpos``/``data.cam_xmat``.

    MuJoCo's ``cam_xmat`` is the camera-to-world rotation of an OpenGL-style camera.

    Shape:
        ``cam_xpos_3`` (3,), ``cam_xmat_9`` (9,) or (3, 3) -> (4, 4) float64.
    """
    pos = np.asarray(cam_xpos_3, dtype=np.float64).reshape(-1)
    mat = np.asarray(cam_xmat_9, dtype=np.float64)
    if pos.shape != (3,) or mat.size != 9:
        raise ShapeError(f"expected cam_xpos (3,) and cam_xmat (9,) or (3, 3), got {pos.shape}, {mat.shape}")
    T = np.eye(4)
    T[:3, :3] = mat.reshape(3, 3)
    T[:3, 3] = pos
    return opengl_to_opencv_pose(T)


def look_at_gl(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Position and 3x3 rotation (columns: camera x, y, z in world) of an OpenGL-style camera
    at ``eye`` looking at ``target`` (the camera looks along its -z axis, y up).
    """
    eye = np.asarray(eye, np.float64)
    back = eye - np.asarray(target, np.float64)
    n = np.linalg.norm(back)
    if n < 1e-9:
        raise ValueError("look_at_gl: eye and target coincide")
    back /= n
    right = np.cross(np.asarray(up, np.float64), back)
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("look_at_gl: viewing direction is parallel to 'up'")
    right /= np.linalg.norm(right)
    upv = np.cross(back, right)
    return eye, np.stack([right, upv, back], axis=1)


_THREAD_GL = threading.local()


def _gl_context(width: int, height: int):
    """The GL context for a new camera: this thread's shared one under EGL (made on first use,
    never freed), else a new context of its own. Returns (context, owned)."""
    from mujoco import gl_context

    if os.environ.get("MUJOCO_GL", "").lower() != "egl":
        return gl_context.GLContext(width, height), True
    gl = getattr(_THREAD_GL, "context", None)
    if gl is None:
        gl = _THREAD_GL.context = gl_context.GLContext(width, height)  # EGL ignores the size
    return gl, False


class MujocoRGBDCamera:
    """A free camera rendering colour, depth and instance segmentation of a MuJoCo model.

    Args:
        model, data: the simulation.
        width, height: image size in pixels.
        fovy_deg: vertical field of view.
        geom_object: per geom id, the object index its pixels report (-1: none).
        fast: turn shadows (and the shadow map), reflections and multisampling off.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        width: int,
        height: int,
        *,
        fovy_deg: float = 60.0,
        geom_object: np.ndarray | None = None,
        fast: bool = True,
    ) -> None:
        if width <= 0 or height <= 0:
            raise ValueError(f"width, height: expected positive sizes, got {width}x{height}")
        if fast:
            model.vis.quality.offsamples = 0
            # No shadows drawn, so no shadow map: the default 4096^2 one took 75-150 ms of every
            # new camera (a new camera per episode), to the same pixels.
            model.vis.quality.shadowsize = 0
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self.model, self.data = model, data
        self.width, self.height = int(width), int(height)
        self.fovy_deg = float(fovy_deg)
        self.K = intrinsics_from_fovy(self.fovy_deg, self.width, self.height)
        self._gl, self._owns_gl = _gl_context(self.width, self.height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._scene = mujoco.MjvScene(model, maxgeom=max(1000, 2 * model.ngeom + 100))
        self._opt = mujoco.MjvOption()
        self._pert = mujoco.MjvPerturb()
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._fast = fast
        lut = np.full(model.ngeom + 1, -1, np.int32)
        if geom_object is not None:
            lut[: model.ngeom] = np.asarray(geom_object, np.int32)
        self._geom_object = lut
        self._rgb = np.empty((self.height, self.width, 3), np.uint8)
        self._ids = np.empty((self.height, self.width, 3), np.uint8)
        self._zbuf = np.empty((self.height, self.width), np.float32)
        extent = model.stat.extent
        self._near = float(model.vis.map.znear * extent)
        self._far = float(model.vis.map.zfar * extent)
        self._pose_gl = np.eye(4)
        self._segid_lut: np.ndarray | None = None  # scene geom index + 1 -> object index

    def set_pose(self, eye, target) -> None:
        """Place the camera at ``eye`` looking at ``target`` (world metres, z up)."""
        pos, rot = look_at_gl(eye, target)
        fwd = -rot[:, 2]
        self._cam.lookat[:] = pos + fwd
        self._cam.distance = 1.0
        self._cam.azimuth = float(np.degrees(np.arctan2(fwd[1], fwd[0])))
        self._cam.elevation = float(np.degrees(np.arcsin(np.clip(fwd[2], -1.0, 1.0))))
        self._pose_gl = np.eye(4)
        self._pose_gl[:3, :3], self._pose_gl[:3, 3] = rot, pos

    def _update(self, segment: bool) -> None:
        self.model.vis.global_.fovy = self.fovy_deg
        mujoco.mjv_updateScene(
            self.model, self.data, self._opt, self._pert, self._cam, mujoco.mjtCatBit.mjCAT_ALL, self._scene
        )
        flags = self._scene.flags
        if self._fast:
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = segment
        flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = segment

    def render(self, *, segmentation: bool = True) -> RGBDFrame:
        """Render the current state from the current pose.

        With ``segmentation=False`` one colour pass gives colour and depth (about twice as
        fast) and ``RGBDFrame.segmentation`` is all -1.

        Shape:
            ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32, ``K`` (3, 3), ``cam_to_world``
            (4, 4), ``segmentation`` (H, W) int32; every array is the frame's own (no buffer
            is shared with the camera).
        """
        self._gl.make_current()
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)  # this camera's buffer
        self._update(segment=False)
        mujoco.mjr_render(self._rect, self._scene, self._ctx)
        if segmentation:
            mujoco.mjr_readPixels(self._rgb, None, self._rect, self._ctx)
            self._update(segment=True)
            mujoco.mjr_render(self._rect, self._scene, self._ctx)
            mujoco.mjr_readPixels(self._ids, self._zbuf, self._rect, self._ctx)
            seg = self._segmentation(np.flipud(self._ids))
        else:
            mujoco.mjr_readPixels(self._rgb, self._zbuf, self._rect, self._ctx)
            seg = np.full((self.height, self.width), -1, np.int32)
        rgb = np.flipud(self._rgb).copy()
        depth = self._metric_depth(np.flipud(self._zbuf))
        # mjv_updateScene recomputes the camera frame; report exactly what was rendered.
        cam_to_world = opengl_to_opencv_pose(self._rendered_pose_gl())
        return RGBDFrame(rgb=rgb, depth=depth, K=self.K.copy(), cam_to_world=cam_to_world, segmentation=seg)

    def _rendered_pose_gl(self) -> np.ndarray:
        # The scene holds a stereo pair offset by half the inter-pupillary distance each;
        # a mono render is taken from their midpoint.
        c0, c1 = self._scene.camera[0], self._scene.camera[1]
        fwd = np.asarray(c0.forward, np.float64)
        up = np.asarray(c0.up, np.float64)
        right = np.cross(fwd, up)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2] = right, up, -fwd
        T[:3, 3] = (np.asarray(c0.pos, np.float64) + np.asarray(c1.pos, np.float64)) / 2
        return T

    def _metric_depth(self, zbuf: np.ndarray) -> np.ndarray:
        # Standard [0, 1] perspective depth buffer: z = near * far / (far - d * (far - near)).
        # float32 keeps sub-millimetre precision at table-top range (relative error ~1e-7 * far/near).
        near, far = self._near, self._far
        with np.errstate(divide="ignore"):
            z = np.float32(near * far) / (np.float32(far) - zbuf * np.float32(far - near))
        z[zbuf >= 1.0] = np.inf  # cleared buffer: nothing hit
        return z

    def _segmentation(self, ids: np.ndarray) -> np.ndarray:
        seg = ids[..., 0].astype(np.int32)
        seg |= ids[..., 1].astype(np.int32) << 8
        seg |= ids[..., 2].astype(np.int32) << 16
        ngeom = self._scene.ngeom
        lut = self._segid_lut
        # The scene lists visible model geoms in model order; the list only changes when the
        # model's visual options do, so the lookup table is rebuilt when its length changes.
        if lut is None or len(lut) != ngeom + 1:
            lut = np.full(ngeom + 1, -1, np.int32)
            for g in self._scene.geoms[:ngeom]:
                if g.segid >= 0 and g.objtype == mujoco.mjtObj.mjOBJ_GEOM:
                    lut[g.segid + 1] = self._geom_object[g.objid]
            self._segid_lut = lut
        np.clip(seg, 0, ngeom, out=seg)
        return lut[seg]

    def close(self) -> None:
        """Release the renderer (and the GL context when the camera has its own)."""
        if self._gl is not None:
            self._gl.make_current()
            self._ctx.free()
            if self._owns_gl:
                self._gl.free()
            self._gl = None

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass
