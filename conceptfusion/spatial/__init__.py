"""conceptfusion.spatial."""
