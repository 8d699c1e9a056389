"""PyBullet backend: scenes as URDF bodies (``scene``), the tiny-renderer/EGL camera
(``camera``), the Franka Panda tabletop with pushes (``tabletop``) and its kinematics twin for
IK and OMPL transit planning (``panda_kinematics``).

May import: :mod:`sim_envs.scenes`, :mod:`sim_envs.assets`, :mod:`planners`, :mod:`conceptfusion`
base modules.
"""
