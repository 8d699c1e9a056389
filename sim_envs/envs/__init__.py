"""sim_envs.envs."""
