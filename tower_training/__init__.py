"""tower_training."""
