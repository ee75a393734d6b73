"""Twin generation: convert Webots worlds to MuJoCo models, check them, and measure their faithfulness."""

from __future__ import annotations

from dualtwin.convert.checks import Finding, SmokeResult, lint_spec, smoke_test
from dualtwin.convert.conversion import Conversion, ConversionError
from dualtwin.convert.equivalences import camera_fovy_degrees, contact_solref, stop_solref, timestep_for
from dualtwin.convert.webots_to_mjcf import convert_loaded, convert_world, convert_world_text

__all__ = [
    "Conversion",
    "ConversionError",
    "Finding",
    "SmokeResult",
    "camera_fovy_degrees",
    "contact_solref",
    "convert_loaded",
    "convert_world",
    "convert_world_text",
    "lint_spec",
    "smoke_test",
    "stop_solref",
    "timestep_for",
]
