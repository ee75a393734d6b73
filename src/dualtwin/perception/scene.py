"""The Webots twin's visual scene: moved to :mod:`dualtwin.webots.visual_scene` (re-exported here).

The runtime's ``Camera`` device draws the same scene, and the Webots runtime is the lowest layer.
"""

from __future__ import annotations

from dualtwin.webots.visual_scene import VISUAL_GEOMETRY, WebotsVisualScene

__all__ = ["VISUAL_GEOMETRY", "WebotsVisualScene"]
