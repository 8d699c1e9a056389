"""conceptfusion.perception.masks."""
