"""The world's light sources (DirectionalLight, PointLight, SpotLight) and where they are now.

A light is a plain node: at the top level its ``location``/``direction`` are world coordinates; inside a Solid
(possibly under ``Pose``/``Transform`` nodes) they are in that frame and the light moves with the Solid, as in
Webots, except a DirectionalLight's ``direction``, which Webots' DirectionalLight page gives "in the global
coordinate system" wherever the node sits (its users read the field as it is). :func:`light_sources` walks the scene
once (and again after a supervisor changed it) and keeps, for each light, the Solid it rides on, its pose in that
Solid's frame and the LED driving it (the light's closest Solid is an LED: :mod:`.led_lights`);
:meth:`LightSource.world_pose` composes the Solid's current pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics import Simulation, SolidRec

__all__ = ["LIGHT_TYPES", "LightSource", "light_sources"]

LIGHT_TYPES = frozenset({"DirectionalLight", "PointLight", "SpotLight"})
_GROUPING = ("children", "endPoint")


@dataclass
class LightSource:
    """One light node, the Solid carrying it (None: the world), its frame in that Solid's frame and the LED that
    switches it (None: its own ``on`` field does)."""

    node: Node
    solid: SolidRec | None
    frame: m3.Pose
    led: Node | None = None

    def world_pose(self, sim: Simulation) -> m3.Pose:
        if self.solid is None:
            return self.frame
        return sim.solid_world_pose(self.solid) * self.frame


def _walk(sim: Simulation, node: Any, solid: SolidRec | None, frame: m3.Pose, out: list[LightSource],
          led: Node | None = None) -> None:
    if not isinstance(node, Node):
        return
    if node.type_name in LIGHT_TYPES:
        out.append(LightSource(node, solid, frame, led))
        return
    rec = sim.solid_for(node)
    if rec is not None:
        # an LED drives the lights among its own children, not those of a Solid inside it (a device of its own)
        solid, frame, led = rec, m3.Pose(), node if node.type_name == "LED" else None
    elif "translation" in node.fields and "rotation" in node.fields:  # Pose / Transform
        frame = frame * m3.Pose.from_fields(node.fields.get("translation"), node.fields.get("rotation"))
    for name in _GROUPING:
        value = node.fields.get(name)
        for child in value if isinstance(value, list) else [value]:
            _walk(sim, child, solid, frame, out, led)


def light_sources(sim: Simulation) -> list[LightSource]:
    """Every light of the world, walked again when a supervisor changed the scene (the geometry version moved:
    a Pose above a light moved, a light imported or removed)."""
    cached = sim.extensions.get("lights")
    if cached is None or cached[0] != sim.geometry_version:
        cached = (sim.geometry_version, [])
        for top in sim.world.nodes:
            _walk(sim, top, None, m3.Pose(), cached[1])
        sim.extensions["lights"] = cached
    return cached[1]  # type: ignore[no-any-return]
