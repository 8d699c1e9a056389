"""agents.spatial."""
