"""harness.maps."""
