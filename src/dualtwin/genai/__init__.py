"""Generative twins: a primitive robot description, an LLM generate-compile-repair loop and a case library."""

from __future__ import annotations
