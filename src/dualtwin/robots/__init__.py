"""Bundled robots and the binding format."""
