"""The PyBullet tabletop backend: a scene plus a Franka Panda that executes push primitives.

The Panda (``franka_panda/panda.urdf`` from ``pybullet_data``) stands on a pedestal at the
centre of the table's -y edge, facing +y, fingers closed. It reaches most of the table, but not
the far corners nor the table right in front of its base: :meth:`PyBulletTabletop.can_reach`
tells. The hand turns so that its narrow side leads the push; above about 4.5 cm over the
fingertip the hand itself is part of the pusher. A push is planned before anything
moves: inverse kinematics with the hand pointing down is solved, in the arm's kinematics twin
(:class:`~sim_envs.pybullet.panda_kinematics.PandaKinematics`), for every waypoint (above the start, the
start at ``PUSH_HEIGHT``, points every 2 cm along the push, above the end; the approach points
high above the objects, or just above the nearby ones where the arm cannot reach that high);
if any waypoint is missed by more than ``reach_tol`` the push
is refused with a reason and the scene is untouched. The two transit moves, from the current
pose to above the start and from above the end back home, are planned in joint space with OMPL
(RRT-Connect, :func:`planners.joint_space.plan_joint_path`) against the table and the objects'
bounding boxes (inflated by ``clearance``) placed in the twin; a transit without a
collision-free path refuses the push. Executing follows the planned joint paths and tracks the
fingertip in straight lines for the rest (a vertical descent, the push at ``push_speed``, a
vertical lift) with joint position control while physics steps, then steps until the objects
are at rest (or ``settle_steps`` have passed).

Deterministic: the same scene, seed and pushes give the same final poses.
"""

from __future__ import annotations

import math

import numpy as np

from conceptfusion.frames import RGBDFrame
from sim_envs.pybullet.panda_kinematics import ARM_JOINTS, BASE_YAW, FINGER_JOINTS, HOME_JOINTS, PANDA_URDF, TIP_LINK, PandaKinematics, load_panda
from sim_envs.pybullet.camera import RENDERERS, PyBulletRGBDCamera, disconnect_quietly, load_egl_plugin
from sim_envs.pybullet.scene import build_pybullet
from sim_envs.scenes.format import Scene
from sim_envs.envs.tabletop_sim import PUSH_HEIGHT, PushOutcome

__all__ = ["PyBulletTabletop", "PANDA_URDF", "HOME_JOINTS"]

_FORCES = (87.0,) * 4 + (12.0,) * 3
_CONTROL_STEPS = 4  # physics steps per control waypoint


class PyBulletTabletop:
    """A :class:`~sim_envs.envs.tabletop_sim.TabletopSim` in PyBullet with a Franka Panda pusher.

    Args:
        scene: the tabletop scene (must have a table).
        seed: recorded for reproducibility; the simulation itself draws no random numbers.
        renderer: "auto", "tiny" or "egl" (see :class:`~sim_envs.pybullet.camera.PyBulletRGBDCamera`).
        time_step: physics step in seconds.
        push_speed: fingertip speed while pushing (m/s); transit moves go at three times this.
        reach_tol: largest inverse-kinematics position error (m) a waypoint may have.
        settle_steps: cap on physics steps spent letting objects come to rest after a push.
        clearance: distance (m) the arm's links keep from the table and the objects' boxes on
            the planned transit moves.
        plan_time: OMPL time limit (s) per transit move.
    """

    def __init__(
        self,
        scene: Scene,
        seed: int = 0,
        *,
        renderer: str = "auto",
        time_step: float = 1.0 / 240.0,
        push_speed: float = 0.15,
        reach_tol: float = 0.01,
        settle_steps: int = 480,
        clearance: float = 0.01,
        plan_time: float = 1.0,
    ) -> None:
        import pybullet as p
        import pybullet_data

        if scene.table is None:
            raise ValueError(f"scene {scene.id!r}: expected a tabletop scene with a table, got table=None")
        if push_speed <= 0 or reach_tol <= 0 or time_step <= 0:
            raise ValueError(f"push_speed, reach_tol, time_step: expected positive values, got {push_speed}, {reach_tol}, {time_step}")
        self.scene = scene
        self.seed = int(seed)
        self.renderer = renderer
        self.push_speed = float(push_speed)
        self.reach_tol = float(reach_tol)
        self.settle_steps = int(settle_steps)
        self._dt = float(time_step)
        self._p = p
        self.client = p.connect(p.DIRECT)
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=self.client)
        p.setTimeStep(self._dt, physicsClientId=self.client)
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=self.client)
        if renderer not in RENDERERS:
            raise ValueError(f"renderer: expected one of {RENDERERS}, got {renderer!r}")
        if renderer != "tiny" and not load_egl_plugin(self.client) and renderer == "egl":
            raise RuntimeError("renderer='egl': PyBullet's EGL plugin (eglRenderer) did not load; use 'tiny' or 'auto'")
        self._sim = build_pybullet(scene, self.client)
        t = scene.table
        self.table_top_z = t.top_z
        self.base_pos = np.array([t.center[0], t.center[1] - t.size[1] / 2 - 0.08, t.top_z])
        base_orn = p.getQuaternionFromEuler([0.0, 0.0, BASE_YAW])
        self.robot = load_panda(p, self.client, self.base_pos, base_orn)
        self.kin = PandaKinematics(self.base_pos, base_orn, reach_tol=reach_tol, clearance=clearance, plan_time=plan_time, seed=self.seed)
        ped_h = t.top_z / 2
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1, 0.1, ped_h], physicsClientId=self.client)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.1, 0.1, ped_h], rgbaColor=[0.3, 0.3, 0.32, 1], physicsClientId=self.client)
        self.pedestal = p.createMultiBody(0.0, col, vis, [*self.base_pos[:2], ped_h], physicsClientId=self.client)
        self._q = np.array(HOME_JOINTS)
        self._hold(self._q)
        self._settle()
        self.home_tip = self._tip()
        self._cameras: dict[tuple, PyBulletRGBDCamera] = {}

    def can_reach(self, xy) -> bool:
        """Whether the fingertip can reach the table point ``xy`` (2,) at ``PUSH_HEIGHT``."""
        xy = np.asarray(xy, np.float64).reshape(-1)
        if xy.shape != (2,):
            raise ValueError(f"xy: expected 2 numbers, got shape {xy.shape}")
        return self.kin.reach(np.array([*xy, self.table_top_z + PUSH_HEIGHT]), self._q)[1] <= self.reach_tol

    # -- state ------------------------------------------------------------------------------
    def object_poses(self) -> np.ndarray:
        """(n, 7) float64: base-centre position xyz and quaternion wxyz, ``scene.objects`` order."""
        p = self._p
        out = np.empty((len(self.scene.objects), 7))
        for i, b in enumerate(self._sim.object_body):
            com_pos, com_orn = p.getBasePositionAndOrientation(int(b), physicsClientId=self.client)
            info = p.getDynamicsInfo(int(b), -1, physicsClientId=self.client)
            inv_pos, inv_orn = p.invertTransform(info[3], info[4])
            pos, orn = p.multiplyTransforms(com_pos, com_orn, inv_pos, inv_orn)
            out[i, :3] = pos
            out[i, 3:] = (orn[3], orn[0], orn[1], orn[2])
        return out

    def object_aabbs(self) -> np.ndarray:
        """(n, 2, 3) world boxes around each object's size box in its current pose."""
        poses = self.object_poses()
        out = np.empty((len(poses), 2, 3))
        for i, (o, pose) in enumerate(zip(self.scene.objects, poses)):
            sx, sy, sz = o.size
            corners = np.array([[x, y, z] for x in (-sx / 2, sx / 2) for y in (-sy / 2, sy / 2) for z in (0.0, sz)])
            R = np.asarray(self._p.getMatrixFromQuaternion([*pose[4:], pose[3]])).reshape(3, 3)
            world = corners @ R.T + pose[:3]
            out[i, 0], out[i, 1] = world.min(0), world.max(0)
        return out

    def _tip(self) -> np.ndarray:
        """World position of the lowest fingertip point (hand pointing down)."""
        ls = self._p.getLinkState(self.robot, TIP_LINK, computeForwardKinematics=True, physicsClientId=self.client)
        return np.asarray(ls[4]) - [0.0, 0.0, self.kin.tip_offset]

    # -- motion -----------------------------------------------------------------------------
    def _hold(self, q) -> None:
        p = self._p
        p.setJointMotorControlArray(
            self.robot, ARM_JOINTS, p.POSITION_CONTROL, targetPositions=[float(v) for v in q], forces=_FORCES,
            physicsClientId=self.client,
        )
        p.setJointMotorControlArray(
            self.robot, FINGER_JOINTS, p.POSITION_CONTROL, targetPositions=[0.0, 0.0], forces=[20.0, 20.0],
            physicsClientId=self.client,
        )

    def _step(self, n: int) -> bool:
        """Step physics n times; True when the arm touched an object meanwhile."""
        p = self._p
        touched = False
        objects = set(self._sim.body_object)
        for _ in range(n):
            p.stepSimulation(physicsClientId=self.client)
            if not touched:
                touched = any(c[2] in objects for c in p.getContactPoints(bodyA=self.robot, physicsClientId=self.client))
        return touched

    def _track(self, a, b, speed: float, path: list) -> bool:
        """Move the fingertip from a to b in a straight line; True on contact with an object."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(1, math.ceil(np.linalg.norm(b - a) / (speed * self._dt * _CONTROL_STEPS)))
        touched = False
        for k in range(1, n + 1):
            target = a + (b - a) * k / n
            self._q, err = self.kin.solve(target + [0.0, 0.0, self.kin.tip_offset], self._q, rounds=2)
            if err > self.reach_tol:
                self._q = self.kin.reach(target, self._q)[0]
            self._hold(self._q)
            touched |= self._step(_CONTROL_STEPS)
            path.append(self._tip())
        return touched

    def _settle(self) -> None:
        p = self._p
        for k in range(self.settle_steps):
            p.stepSimulation(physicsClientId=self.client)
            if k >= 24 and k % 8 == 0:
                moving = False
                for b in self._sim.object_body:
                    lin, ang = p.getBaseVelocity(int(b), physicsClientId=self.client)
                    if np.linalg.norm(lin) > 2e-3 or np.linalg.norm(ang) > 2e-2:
                        moving = True
                        break
                if not moving:
                    return

    # -- the primitive ----------------------------------------------------------------------
    # -- transit planning (OMPL, in the kinematics twin) ---------------------------------------
    def _place_obstacles(self) -> None:
        """The table top and every object's current box, as the twin's obstacles."""
        t = self.scene.table
        boxes = [(np.array([*t.center[:2], t.top_z - 0.025]), np.array([t.size[0] / 2, t.size[1] / 2, 0.025]))]
        for lo, hi in self.object_aabbs():
            boxes.append(((lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-3)))
        self.kin.set_obstacles(boxes)

    def _follow(self, path_q: np.ndarray, path: list) -> bool:
        """Drive the arm along a joint path, at most 0.03 rad per control waypoint."""
        touched = False
        for a, b in zip(path_q[:-1], path_q[1:]):
            n = max(1, math.ceil(float(np.max(np.abs(b - a))) / 0.03))
            for k in range(1, n + 1):
                self._q = a + (b - a) * k / n
                self._hold(self._q)
                touched |= self._step(_CONTROL_STEPS)
            path.append(self._tip())
        return touched

    def push(self, start_xy, direction_rad: float, distance: float) -> PushOutcome:
        """Push from ``start_xy`` along world yaw ``direction_rad`` for ``distance`` metres
        (see :meth:`sim_envs.envs.tabletop_sim.TabletopSim.push`).

        Shape:
            ``start_xy`` (2,); ``PushOutcome.fingertip_path`` (m, 3).
        """
        start = np.asarray(start_xy, np.float64).reshape(-1)
        if start.shape != (2,) or not np.all(np.isfinite(start)):
            raise ValueError(f"start_xy: expected 2 finite numbers, got {start_xy!r}")
        if not (math.isfinite(direction_rad) and math.isfinite(distance) and distance >= 0):
            raise ValueError(f"direction_rad, distance: expected finite numbers and distance >= 0, got {direction_rad}, {distance}")
        none = np.empty((0, 3))
        aabbs = self.object_aabbs()
        z_push = self.table_top_z + PUSH_HEIGHT
        for i, (lo, hi) in enumerate(aabbs):
            if hi[2] > z_push and np.all(start >= lo[:2] - 0.01) and np.all(start <= hi[:2] + 0.01):
                o = self.scene.objects[i]
                return PushOutcome(False, f"start point {start.round(3).tolist()} lies over object {o.id!r} ({o.name}); the fingertip would land on it", False, none)
        safe_z = max(self.table_top_z + 0.25, float(aabbs[:, 1, 2].max(initial=0.0)) + 0.10)
        d = np.array([math.cos(direction_rad), math.sin(direction_rad), 0.0])
        # The hand's long side (across the fingers) turns perpendicular to the push, so what
        # leads is the narrow side of the fingers and hand.
        # Of the two equivalent yaws, the one nearer the base's keeps the wrist mid-range.
        hand_yaw = BASE_YAW + ((direction_rad - BASE_YAW + math.pi / 2) % math.pi - math.pi / 2)
        self.kin.down = self._p.getQuaternionFromEuler([math.pi, 0.0, hand_yaw])
        p0 = np.array([*start, z_push])
        p1 = p0 + distance * d
        n_mid = max(1, math.ceil(distance / 0.02))
        def approach_heights(xy) -> list[float]:
            # High above everything first; where the arm cannot reach that high (far from its
            # base), just above what stands within 15 cm: the transit to it is planned around
            # the objects anyway, and the way down is vertical over a free start point.
            near = np.linalg.norm((aabbs[:, 0, :2] + aabbs[:, 1, :2]) / 2 - xy, axis=1) < 0.15
            low = max(z_push + 0.08, float(aabbs[near, 1, 2].max(initial=0.0)) + 0.05)
            return [safe_z] + ([low] if low < safe_z - 1e-6 else [])

        plan = [("above the start", [np.array([*start, z]) for z in approach_heights(start)]), ("the start", [p0])]
        plan += [("a point along the push", [p0 + (p1 - p0) * k / n_mid]) for k in range(1, n_mid)]
        plan += [("the end", [p1]), ("above the end", [np.array([*p1[:2], z]) for z in approach_heights(p1[:2])])]
        q = self._q
        solved, waypoints = [], []
        for label, options in plan:
            for point in options:
                q_try, err = self.kin.reach(point, q)
                if err <= self.reach_tol:
                    break
            if err > self.reach_tol:
                return PushOutcome(
                    False, f"the arm cannot reach {label} {point.round(3).tolist()} (IK error {100 * err:.1f} cm > {100 * self.reach_tol:.1f} cm)", False, none,
                )
            q = q_try
            solved.append(q)
            waypoints.append(point)
        self._place_obstacles()
        there, why = self.kin.plan_transit(self._q, solved[0], "above the start")
        back = None
        if there is not None:
            back, why = self.kin.plan_transit(solved[-1], np.array(HOME_JOINTS), "the home pose")
        if there is None or back is None:
            return PushOutcome(False, why, False, none)
        path: list[np.ndarray] = [self._tip()]
        fast = 3 * self.push_speed
        touched = self._follow(there, path)
        touched |= self._track(waypoints[0], p0, fast, path)
        touched |= self._track(p0, p1, self.push_speed, path)
        touched |= self._track(p1, waypoints[-1], fast, path)
        back[0] = self._q  # start from where the lift ended
        touched |= self._follow(back, path)
        self._settle()
        return PushOutcome(True, "", bool(touched), np.asarray(path))

    # -- rendering --------------------------------------------------------------------------
    def render(self, eye, target, width: int, height: int, fovy_deg: float = 60.0, segmentation: bool = True) -> RGBDFrame:
        """One posed RGB-D frame: OpenCV camera, metric depth, segmentation = object index.

        Shape:
            see :class:`~conceptfusion.frames.RGBDFrame`.
        """
        key = (int(width), int(height), float(fovy_deg))
        cam = self._cameras.get(key)
        if cam is None:
            cam = PyBulletRGBDCamera(self.client, width, height, fovy_deg=fovy_deg, body_object=self._sim.body_lut(), renderer=self.renderer)
            self._cameras[key] = cam
        cam.set_pose(eye, target)
        return cam.render(segmentation=segmentation)

    def close(self) -> None:
        """Disconnect the simulation and the kinematics twin (idempotent)."""
        try:
            disconnect_quietly(self.client)
        except Exception:  # already disconnected
            pass
        self.kin.close()
        self._cameras.clear()
