"""conceptfusion."""
