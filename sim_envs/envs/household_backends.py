"""A household scene loaded in one simulator, with its RGB-D camera: what ``ObjectSearch`` and
``SceneScan`` hold, the same for MuJoCo and PyBullet.

Both backends build the same scene description (:func:`sim_envs.mujoco.scene.build_mujoco`,
:func:`sim_envs.pybullet.scene.build_pybullet`), render with the same camera conventions (OpenCV
``cam_to_world``, ``K`` from the vertical field of view with the principal point at the image
centre, metric depth along the optical axis, ``inf`` where nothing is hit) and label pixels the
same way: object index, or with ``labels="objects+furniture"`` furniture ``j`` as
``num_objects + j`` (:func:`sim_envs.mujoco.scene.split_labels`), -1 elsewhere. Everything
else the environments do (base kinematics on the floor plan's grid, collisions, success) is
computed from the scene description and the boxes of :func:`sim_envs.scenes.graph.object_aabbs`,
so it is shared.

PyBullet renders with its EGL plugin when it loads (the principal point then matches MuJoCo's)
and with its tiny software renderer otherwise (``K`` says where its principal point is).
"""

from __future__ import annotations

from conceptfusion.errors import SimError
from sim_envs.envs.checks import check_choice

__all__ = ["HOUSEHOLD_BACKENDS", "LABELS", "HouseholdBackend", "check_backend"]

HOUSEHOLD_BACKENDS = {
    "mujoco": "MuJoCo: build_mujoco and MujocoRGBDCamera (EGL)",
    "pybullet": "PyBullet (DIRECT): build_pybullet and PyBulletRGBDCamera (EGL plugin, else the tiny renderer)",
}
"""Simulators a household environment runs on, by the name its ``backend`` argument takes."""

LABELS = ("objects", "objects+furniture")
"""What segmentation pixels report: object indices only, or objects then furniture."""

_FAR = 50.0  # metres: past any apartment (MuJoCo's far plane is 50 x the model's extent)


def check_backend(where: str, backend) -> str:
    """``backend`` when it names one of :data:`HOUSEHOLD_BACKENDS`; else
    :class:`~conceptfusion.errors.UnknownNameError` naming the field, the choices and the nearest."""
    return check_choice(where, "backend", backend, HOUSEHOLD_BACKENDS)


class HouseholdBackend:
    """A scene in one simulator and (optionally) a camera over it.

    Args:
        backend: a key of :data:`HOUSEHOLD_BACKENDS`.
        scene: the scene to build (a household or, for ``SceneScan``, a tabletop).
        camera: ``(width, height, fovy_deg)`` of the camera to make, or None for none.
        labels: one of :data:`LABELS`.
        source: how errors name the scene (its file); default its id.

    ``sim`` is what :func:`~sim_envs.scenes.graph.scene_graph` and
    :func:`~sim_envs.scenes.graph.object_aabbs` read; ``camera`` has ``set_pose(eye, target)``
    and ``render(segmentation=...)``. :meth:`close` releases both.
    """

    def __init__(self, backend: str, scene, *, camera: tuple[int, int, float] | None, labels: str = "objects",
                 source: str | None = None) -> None:
        if labels not in LABELS:
            raise SimError(f"labels: expected one of {LABELS}, got {labels!r}")
        self.backend = backend
        self.camera = None
        self._client = None
        if backend == "mujoco":
            self._load_mujoco(scene, camera, labels)
        elif backend == "pybullet":
            self._load_pybullet(scene, camera, labels, source)
        else:
            check_backend("HouseholdBackend", backend)

    def _load_mujoco(self, scene, camera, labels: str) -> None:
        from sim_envs.mujoco.camera import MujocoRGBDCamera
        from sim_envs.mujoco.scene import build_mujoco

        self.sim = build_mujoco(scene)
        if camera is not None:
            width, height, fovy = camera
            lut = self.sim.geom_object if labels == "objects" else self.sim.geom_labels()
            self.camera = MujocoRGBDCamera(self.sim.model, self.sim.data, width, height, fovy_deg=fovy, geom_object=lut)

    def _load_pybullet(self, scene, camera, labels: str, source: str | None) -> None:
        import pybullet as p

        from sim_envs.pybullet.camera import PyBulletRGBDCamera, load_egl_plugin
        from sim_envs.pybullet.scene import build_pybullet

        self._client = p.connect(p.DIRECT)
        try:
            if camera is not None:
                load_egl_plugin(self._client)  # before any body: the plugin draws only bodies made after it
            self.sim = build_pybullet(scene, self._client, source=source)
            if camera is not None:
                width, height, fovy = camera
                lut = self.sim.body_lut() if labels == "objects" else self.sim.body_labels()
                self.camera = PyBulletRGBDCamera(self._client, width, height, fovy_deg=fovy, body_object=lut, far=_FAR)
                self.camera.warm_up()  # seeded resets repeat their first observation
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the camera and the simulation (idempotent)."""
        if self.camera is not None:
            self.camera.close()
            self.camera = None
        if self._client is not None:
            from sim_envs.pybullet.camera import disconnect_quietly

            try:
                disconnect_quietly(self._client)
            finally:
                self._client = None
