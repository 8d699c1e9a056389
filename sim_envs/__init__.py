"""sim_envs."""
