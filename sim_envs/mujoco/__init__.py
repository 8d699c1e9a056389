"""sim_envs.mujoco."""
