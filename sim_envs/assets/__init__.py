"""sim_envs.assets."""
