"""sim_envs.scenes."""
