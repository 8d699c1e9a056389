"""The Franka Panda's kinematics twin: inverse kinematics with the hand pointing down, and
collision-free transit planning in joint space with OMPL.

The twin is a second Panda in its own PyBullet ``DIRECT`` client with nothing but static boxes
around it, so that planning never touches the simulated scene. :meth:`PandaKinematics.reach`
solves IK for a fingertip point (from the given seed, then from fixed seeds);
:meth:`PandaKinematics.plan_transit` plans RRT-Connect (:func:`planners.joint_space.plan_joint_path`)
between two joint configurations against the boxes last given to
:meth:`PandaKinematics.set_obstacles`, keeping every link but the two on the pedestal
``clearance`` away from them.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PandaKinematics", "load_panda", "PANDA_URDF", "HOME_JOINTS", "ARM_JOINTS", "FINGER_JOINTS", "BASE_YAW", "TIP_LINK"]

PANDA_URDF = "franka_panda/panda.urdf"
"""The arm, inside ``pybullet_data``."""

HOME_JOINTS = (0.0, -1.0, 0.0, -2.6, 0.0, 1.75, math.pi / 4)
"""Arm joint angles of the home pose: hand raised above the table edge, out of the way."""

ARM_JOINTS = tuple(range(7))
FINGER_JOINTS = (9, 10)
BASE_YAW = math.pi / 2  # the arm faces +y
TIP_LINK = 11  # panda_grasptarget, the point IK places
_JOINT_LO = np.array([-2.9671, -1.8326, -2.9671, -3.0718, -2.9671, -0.0175, -2.9671])
_JOINT_HI = np.array([2.9671, 1.8326, 2.9671, -0.0698, 2.9671, 3.7525, 2.9671])
_CHECKED_LINKS = tuple(range(2, 12))  # links 0-1 sit on the pedestal at the table's edge
_IK_SEEDS = (  # tried in turn when the current configuration does not lead to a solution
    HOME_JOINTS,
    (0.0, 0.3, 0.0, -2.2, 0.0, 2.5, math.pi / 4),
    (0.0, -0.3, 0.0, -2.9, 0.0, 2.6, math.pi / 4),
    (0.0, 0.6, 0.0, -1.2, 0.0, 1.8, math.pi / 4),
)


def load_panda(p, client: int, base_pos, orn) -> int:
    """Load the Panda, fixed base, at home with closed fingers, into ``client``; its body id."""
    body = p.loadURDF(PANDA_URDF, list(map(float, base_pos)), orn, useFixedBase=True, physicsClientId=client)
    for j, q in zip(ARM_JOINTS, HOME_JOINTS):
        p.resetJointState(body, j, q, physicsClientId=client)
    for j in FINGER_JOINTS:
        p.resetJointState(body, j, 0.0, physicsClientId=client)
    return body


class PandaKinematics:
    """The kinematics twin of a Panda standing at ``base_pos`` (see the module docstring).

    Args:
        base_pos: (3,) world position of the arm's base; ``base_orn`` its quaternion (xyzw).
        reach_tol: largest IK position error (m) :meth:`reach` accepts before trying other seeds.
        clearance: distance (m) the links keep from the obstacle boxes on planned transits.
        plan_time: OMPL time limit (s) per transit.
        seed: base of the planners' seeds (each plan draws the next one).

    Attributes:
        down: the hand orientation IK solves for (pointing down; its yaw may be changed).
        tip_offset: height of the grasp-target frame above the lowest finger point (m).
    """

    def __init__(self, base_pos, base_orn, *, reach_tol: float = 0.01, clearance: float = 0.01, plan_time: float = 1.0, seed: int = 0) -> None:
        import pybullet as p
        import pybullet_data

        self._p = p
        self.reach_tol, self.clearance, self.plan_time, self.seed = float(reach_tol), float(clearance), float(plan_time), int(seed)
        self.client = p.connect(p.DIRECT)
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=self.client)
        self.body = load_panda(p, self.client, base_pos, base_orn)
        self.down = p.getQuaternionFromEuler([math.pi, 0.0, BASE_YAW])
        self._obstacles: list[int] = []
        self._plans = 0
        q = self.solve(np.asarray(base_pos, float) + [0.0, 0.45, 0.3], np.array(HOME_JOINTS))[0]
        self.set_q(q)
        tip = np.array(p.getLinkState(self.body, TIP_LINK, computeForwardKinematics=True, physicsClientId=self.client)[4])
        low = min(p.getAABB(self.body, j, physicsClientId=self.client)[0][2] for j in FINGER_JOINTS)
        self.tip_offset = float(tip[2] - low)

    def set_q(self, q) -> None:
        """Put the twin's arm at joint angles ``q`` (7,)."""
        for j, v in zip(ARM_JOINTS, q):
            self._p.resetJointState(self.body, j, float(v), physicsClientId=self.client)

    def solve(self, tip_target, seed_q: np.ndarray, rounds: int = 4) -> tuple[np.ndarray, float]:
        """Joint angles putting the grasp target at ``tip_target`` (3,) with the hand
        :attr:`down`, and the remaining position error (m)."""
        p = self._p
        lo = [*_JOINT_LO, 0.0, 0.0]
        hi = [*_JOINT_HI, 0.04, 0.04]
        ranges = [h - l for l, h in zip(lo, hi)]
        target = [float(x) for x in tip_target]
        q = np.asarray(seed_q, np.float64)
        rest = [float(v) for v in q] + [0.0, 0.0]
        err = math.inf
        for _ in range(rounds):
            self.set_q(q)
            sol = p.calculateInverseKinematics(
                self.body, TIP_LINK, target, self.down, lowerLimits=lo, upperLimits=hi, jointRanges=ranges,
                restPoses=rest, maxNumIterations=200, residualThreshold=1e-5, physicsClientId=self.client,
            )
            q = np.clip(np.asarray(sol[:7]), lo[:7], hi[:7])
            self.set_q(q)
            got = p.getLinkState(self.body, TIP_LINK, computeForwardKinematics=True, physicsClientId=self.client)[4]
            err = float(np.linalg.norm(np.asarray(got) - target))
            if err < 1e-3:
                break
        return q, err

    def reach(self, tip, seed_q) -> tuple[np.ndarray, float]:
        """IK for a fingertip point (3,), from ``seed_q`` and then from fixed seeds until one is
        within ``reach_tol``; returns the best joint angles and their error (m)."""
        target = np.asarray(tip, np.float64) + [0.0, 0.0, self.tip_offset]
        best = self.solve(target, seed_q)
        for seed in _IK_SEEDS:
            if best[1] <= self.reach_tol:
                break
            cand = self.solve(target, np.array(seed), rounds=8)
            if cand[1] < best[1]:
                best = cand
        return best

    def set_obstacles(self, boxes) -> None:
        """Replace the static obstacles by axis-aligned boxes ``(centre (3,), half extents (3,))``."""
        p = self._p
        for b in self._obstacles:
            p.removeBody(b, physicsClientId=self.client)
        self._obstacles = []
        for centre, half in boxes:
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[float(h) for h in half], physicsClientId=self.client)
            self._obstacles.append(p.createMultiBody(0.0, col, -1, [float(c) for c in centre], physicsClientId=self.client))

    def config_free(self, q) -> bool:
        """True when the arm at joint angles ``q`` (7,) keeps ``clearance`` from every obstacle
        (links on the pedestal excluded)."""
        p = self._p
        self.set_q(q)
        for b in self._obstacles:
            for link in _CHECKED_LINKS:
                if p.getClosestPoints(self.body, b, self.clearance, linkIndexA=link, physicsClientId=self.client):
                    return False
        return True

    def plan_transit(self, q0, q1, label: str) -> tuple[np.ndarray | None, str]:
        """An OMPL joint path from ``q0`` to ``q1``, (N, 7), or ``None`` and the reason there is none."""
        from planners.joint_space import plan_joint_path

        self._plans += 1
        res = plan_joint_path(
            np.clip(q0, _JOINT_LO, _JOINT_HI), np.clip(q1, _JOINT_LO, _JOINT_HI), _JOINT_LO, _JOINT_HI, self.config_free,
            time_limit=self.plan_time, seed=self.seed * 1000 + self._plans, resolution=0.02, simplify_time=self.plan_time,
        )
        if not res.solved:
            return None, f"no collision-free arm motion to {label} ({res.status}: {res.reason})"
        return np.array(res.path, dtype=np.float64), ""

    def close(self) -> None:
        """Disconnect the twin's client (idempotent)."""
        try:
            self._p.disconnect(physicsClientId=self.client)
        except Exception:  # already disconnected
            pass
