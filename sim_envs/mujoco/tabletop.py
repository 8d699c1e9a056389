"""The MuJoCo backend of ``TabletopRearrange``: a scene plus a kinematic fingertip that pushes.

The fingertip is a vertical capsule (radius 1.5 cm) on three slide joints. Its joints are driven
kinematically: before every physics step their position and velocity are overwritten with the
planned trajectory, so the fingertip is infinitely strong and exactly repeatable, while objects
see its true velocity in the contact solver. It collides with objects only (never with the table
or the floor). Between pushes it is parked below the floor, out of every camera's view.

Objects slide with friction 0.4 on the table, the fingertip grips with friction 1.0, and their rotational degrees of freedom carry a
little damping so that balls stop rolling and pushed objects do not spin or tumble freely.

Objects at rest sleep (MuJoCo's island sleeping, ``mjENBL_SLEEP``): a body whose speed has stayed
under ``opt.sleep_tolerance`` for a few steps is no longer integrated until something awake
touches it or its state is written (``set_object_pose``). The fingertip never sleeps (its body's
``sleep="never"``), so it wakes whatever it touches. Most of a push's physics steps used to go to
objects resting on the table; asleep, they cost almost nothing (an episode runs 3-8 times faster),
and the calibrated success rates of every pusher moved by at most 2 episodes in 150.
"""

from __future__ import annotations

import numpy as np

from sim_envs import headless  # noqa: F401  (selects the GL backend before mujoco loads)

import mujoco  # noqa: E402

from conceptfusion.frames import RGBDFrame  # noqa: E402
from sim_envs.mujoco.camera import MujocoRGBDCamera  # noqa: E402
from sim_envs.mujoco.scene import MujocoScene, build_mjcf  # noqa: E402
from sim_envs.scenes.format import Scene  # noqa: E402
from sim_envs.scenes.graph import object_aabbs  # noqa: E402
from sim_envs.envs.tabletop_sim import PUSH_HEIGHT, PushOutcome  # noqa: E402

__all__ = ["MujocoTabletop", "FINGER_RADIUS", "PUSH_SPEED"]

FINGER_RADIUS = 0.015
"""Radius of the capsule fingertip (metres)."""
PUSH_SPEED = 0.1
"""Fingertip speed while pushing (m/s)."""
_MOVE_SPEED = 0.3  # descending and lifting (m/s)
_FINGER_HALF = 0.06  # half-length of the capsule's straight part
_OBJECT_FRICTION = (0.4, 0.005, 0.0001)  # MuJoCo takes the larger of two geoms' coefficients,
_TABLE_FRICTION = (0.4, 0.005, 0.0001)  # so table and objects both set the sliding friction
_FINGER_FRICTION = (1.0, 0.005, 0.0001)  # a rubber tip: sticks rather than slides on objects
_ROT_DAMPING = 0.004  # N m s / rad on every object's rotational dofs
_SETTLE_SPEED = 0.005  # m/s: objects count as settled below this
_SETTLE_SPIN = 0.05  # rad/s
_SETTLE_CAP_S = 2.0
_PATH_EVERY = 25  # record every n-th fingertip position


def _as_slice(index: np.ndarray):
    """``index`` as a slice when it is consecutive (else as it is)."""
    index = np.asarray(index)
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def _pusher_xml(park: tuple[float, float, float]) -> str:
    x, y, z = park
    return (
        f'<body name="pusher" pos="{x} {y} {z}" sleep="never">'
        '<joint name="pusher_x" type="slide" axis="1 0 0" armature="10"/>'
        '<joint name="pusher_y" type="slide" axis="0 1 0" armature="10"/>'
        '<joint name="pusher_z" type="slide" axis="0 0 1" armature="10"/>'
        f'<geom name="fingertip" type="capsule" fromto="0 0 0 0 0 {2 * _FINGER_HALF}" size="{FINGER_RADIUS}" '
        f'mass="5" rgba="0.2 0.2 0.25 1" friction="{" ".join(map(str, _FINGER_FRICTION))}"/>'
        "</body>"
    )


class MujocoTabletop:
    """A tabletop scene in MuJoCo with a kinematic capsule fingertip (implements ``TabletopSim``).

    Args:
        scene: the scene to load (needs a table).
        seed: accepted for interface parity with other backends; MuJoCo runs deterministically,
            so the same scene and the same pushes always give the same states.
    """

    def __init__(self, scene: Scene, seed: int = 0) -> None:
        if scene.table is None:
            raise ValueError(f"scene {scene.id}: the tabletop backend needs a scene with a table, got none")
        self.scene = scene
        self.seed = int(seed)
        self._park = (float(scene.table.center[0]), float(scene.table.center[1]), -0.5)
        xml = build_mjcf(scene)
        xml = xml.replace("</worldbody>", _pusher_xml(self._park) + "</worldbody>", 1)
        xml = xml.replace("</mujoco>", '<contact><exclude body1="world" body2="pusher"/></contact></mujoco>', 1)
        model = mujoco.MjModel.from_xml_string(xml)
        # Sleeping before the data exists: MjData sets every tree's sleep state from the flag.
        model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        data = mujoco.MjData(model)
        body_object = np.full(model.nbody, -1, np.int32)
        object_body = np.empty(len(scene.objects), np.int32)
        for i, o in enumerate(scene.objects):
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, o.id)
            body_object[b], object_body[i] = i, b
        geom_object = body_object[model.geom_bodyid]
        self.mj = MujocoScene(scene, model, data, geom_object, object_body)
        self._finger_geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "fingertip")
        joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"pusher_{a}") for a in "xyz"]
        # The pusher's x, y, z joints are consecutive, so plain slices address them (a tenth of the
        # cost of index arrays in the physics loop, where they are set every step).
        self._finger_q = _as_slice(np.array([model.jnt_qposadr[j] for j in joints]))
        self._finger_v = _as_slice(np.array([model.jnt_dofadr[j] for j in joints]))
        self._park_v = np.array(self._park)
        self._obj_qpos = np.array([model.jnt_qposadr[model.body_jntadr[b]] for b in object_body], np.int64)
        self._obj_dof = np.array([model.jnt_dofadr[model.body_jntadr[b]] for b in object_body], np.int64)
        obj_geoms = geom_object >= 0
        model.geom_friction[obj_geoms] = _OBJECT_FRICTION
        model.geom_friction[~obj_geoms] = _TABLE_FRICTION
        model.geom_friction[self._finger_geom] = _FINGER_FRICTION
        for d in self._obj_dof:
            model.dof_damping[d + 3 : d + 6] = _ROT_DAMPING
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        self._cameras: dict[tuple, MujocoRGBDCamera] = {}
        self._set_finger(np.array(self._park), np.zeros(3))
        mujoco.mj_forward(model, data)
        self._settle()

    # ---------------------------------------------------------------- state
    @property
    def model(self) -> mujoco.MjModel:
        return self.mj.model

    @property
    def data(self) -> mujoco.MjData:
        return self.mj.data

    def object_poses(self) -> np.ndarray:
        """(n, 7) base-centre xyz and quaternion wxyz of every object, in ``scene.objects`` order."""
        idx = self._obj_qpos[:, None] + np.arange(7)[None, :]
        return self.data.qpos[idx].astype(np.float64).copy()

    def object_aabbs(self) -> np.ndarray:
        """(n, 2, 3) world axis-aligned boxes (lower, upper corner) of every object now."""
        return object_aabbs(self.mj)

    def set_object_pose(self, index: int, position, quat_wxyz=None) -> None:
        """Place object ``index`` at ``position`` (base centre, (3,)) with ``quat_wxyz`` (4,) (kept
        when omitted), at rest. For tests and scripted set-ups; runs one forward pass."""
        if not 0 <= index < len(self.scene.objects):
            raise ValueError(f"index: expected 0..{len(self.scene.objects) - 1}, got {index}")
        a = self._obj_qpos[index]
        self.data.qpos[a : a + 3] = np.asarray(position, np.float64).reshape(3)
        if quat_wxyz is not None:
            q = np.asarray(quat_wxyz, np.float64).reshape(4)
            self.data.qpos[a + 3 : a + 7] = q / np.linalg.norm(q)
        d = self._obj_dof[index]
        self.data.qvel[d : d + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)

    # ---------------------------------------------------------------- pushing
    def push(self, start_xy, direction_rad: float, distance: float) -> PushOutcome:
        """Descend at ``start_xy``, push ``distance`` metres along world yaw ``direction_rad`` at
        ``PUSH_SPEED``, lift and let the objects settle.

        Not executed (nothing moves) when the start point is off the table or the fingertip,
        lowered there, would overlap an object.
        """
        start = np.asarray(start_xy, np.float64).reshape(-1)
        if start.shape != (2,) or not np.all(np.isfinite(start)):
            raise ValueError(f"start_xy: expected 2 finite numbers, got {start_xy!r}")
        if not np.isfinite(direction_rad) or not np.isfinite(distance) or distance < 0:
            raise ValueError(f"direction_rad, distance: expected finite values and distance >= 0, got {direction_rad!r}, {distance!r}")
        t = self.scene.table
        half = np.array(t.size[:2]) / 2
        if np.any(np.abs(start - np.array(t.center[:2])) > half):
            return PushOutcome(False, f"start point {start.round(3).tolist()} is off the table", False, np.zeros((0, 3)))
        push_z = t.top_z + PUSH_HEIGHT
        blocker = self._overlap_at(np.array([start[0], start[1], push_z]))
        if blocker is not None:
            return PushOutcome(
                False, f"start point {start.round(3).tolist()} is inside the footprint of {self.scene.objects[blocker].id}", False, np.zeros((0, 3))
            )
        safe_z = max(float(self.object_aabbs()[:, 1, 2].max()) if len(self.scene.objects) else t.top_z, t.top_z) + 0.03
        direction = np.array([np.cos(direction_rad), np.sin(direction_rad), 0.0])
        above = np.array([start[0], start[1], safe_z])
        low = np.array([start[0], start[1], push_z])
        end = low + float(distance) * direction
        path: list[np.ndarray] = []
        contact = False
        contact |= self._move(above, above, _MOVE_SPEED, path)  # appear above the start point
        contact |= self._move(above, low, _MOVE_SPEED, path)
        contact |= self._move(low, end, PUSH_SPEED, path)
        contact |= self._move(end, np.array([end[0], end[1], safe_z]), _MOVE_SPEED, path)
        self._set_finger(np.array(self._park), np.zeros(3))
        self._settle()
        return PushOutcome(True, "", bool(contact), np.array(path).reshape(-1, 3))

    def _overlap_at(self, pos: np.ndarray) -> int | None:
        """Index of an object the fingertip would penetrate at ``pos``; the state is restored."""
        saved_q, saved_v = self.data.qpos.copy(), self.data.qvel.copy()
        self._set_finger(pos, np.zeros(3))
        mujoco.mj_forward(self.model, self.data)
        hit = None
        for c in self.data.contact[: self.data.ncon]:
            if c.dist < -1e-4 and self._finger_geom in (c.geom1, c.geom2):
                other = c.geom2 if c.geom1 == self._finger_geom else c.geom1
                if self.mj.geom_object[other] >= 0:
                    hit = int(self.mj.geom_object[other])
                    break
        self.data.qpos[:], self.data.qvel[:] = saved_q, saved_v
        mujoco.mj_forward(self.model, self.data)
        return hit

    def _set_finger(self, pos: np.ndarray, vel: np.ndarray) -> None:
        self.data.qpos[self._finger_q] = np.asarray(pos) - self._park_v
        self.data.qvel[self._finger_v] = vel

    def _move(self, a: np.ndarray, b: np.ndarray, speed: float, path: list) -> bool:
        """Drive the fingertip from ``a`` to ``b`` at ``speed`` while physics steps; True on contact."""
        dt = self.model.opt.timestep
        length = float(np.linalg.norm(b - a))
        n = max(1, int(np.ceil(length / (speed * dt))))
        vel = (b - a) / (n * dt)
        # Every waypoint at once (the same arithmetic per element as one at a time), then the
        # loop only sets the joints and steps.
        points = a + (b - a) * (np.arange(1, n + 1) / n)[:, None]
        joints = points - self._park_v
        model, data, qpos, qvel, fq, fv = self.model, self.data, self.data.qpos, self.data.qvel, self._finger_q, self._finger_v
        touched = False
        for k in range(1, n + 1):
            qpos[fq] = joints[k - 1]
            qvel[fv] = vel
            mujoco.mj_step(model, data)
            if k % _PATH_EVERY == 0 or k == n:
                path.append(points[k - 1].copy())
            if not touched and self._finger_touches():
                touched = True
        self._set_finger(b, np.zeros(3))
        return touched

    def _finger_touches(self) -> bool:
        ncon = self.data.ncon
        return bool(np.any(self.data.contact.geom[:ncon] == self._finger_geom)) if ncon else False

    def _settle(self) -> None:
        """Step until every object is nearly at rest (capped at ``_SETTLE_CAP_S`` of sim time)."""
        dt = self.model.opt.timestep
        idx = self._obj_dof[:, None] + np.arange(6)[None, :]
        zero = np.zeros(3)
        for _ in range(int(_SETTLE_CAP_S / dt)):
            mujoco.mj_step(self.model, self.data)
            self._set_finger(self._park_v, zero)
            v = self.data.qvel[idx] if len(self._obj_dof) else np.zeros((0, 6))
            if not len(v) or (np.abs(v[:, :3]).max() < _SETTLE_SPEED and np.abs(v[:, 3:]).max() < _SETTLE_SPIN):
                break

    # ---------------------------------------------------------------- rendering
    def render(self, eye, target, width: int, height: int, fovy_deg: float = 60.0, segmentation: bool = True) -> RGBDFrame:
        """One posed RGB-D frame (OpenCV camera, metric depth, segmentation = object index or -1)."""
        key = (int(width), int(height), float(fovy_deg))
        cam = self._cameras.get(key)
        if cam is None:
            cam = MujocoRGBDCamera(self.model, self.data, key[0], key[1], fovy_deg=key[2], geom_object=self.mj.geom_object)
            self._cameras[key] = cam
        cam.set_pose(eye, target)
        return cam.render(segmentation=segmentation)

    def close(self) -> None:
        """Release the renderers."""
        for cam in self._cameras.values():
            cam.close()
        self._cameras.clear()
