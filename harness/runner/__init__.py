"""harness.runner."""
