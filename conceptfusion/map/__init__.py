"""conceptfusion.map."""
