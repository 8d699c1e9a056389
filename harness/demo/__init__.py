"""harness.demo."""
