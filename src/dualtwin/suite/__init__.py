"""Scenario suites: format, loading and running."""
