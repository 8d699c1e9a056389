"""sim_envs.pybullet."""
