"""conceptfusion.perception."""
