"""Pen: the API of Webots' drawing pen. Ink is visual only in Webots (it paints textures, with no physical
effect), and the headless twin renders no textures, so the pen keeps its state and draws nothing."""

from __future__ import annotations

from typing import Any

from dualtwin.webots.api_args import as_float, as_int, warn
from dualtwin.webots.device_base import Device

__all__ = ["Pen"]


class Pen(Device):
    """Webots ``Pen``: ``write`` switches the ink on or off, ``setInkColor`` sets its colour and density."""

    def write(self, write: Any) -> None:
        self._record.node.fields["write"] = bool(write)

    def setInkColor(self, color: Any, density: Any) -> None:
        rgb = as_int(color, "Pen.setInkColor")
        d = as_float(density, "Pen.setInkColor")
        if not 0 <= rgb <= 0xFFFFFF or not 0.0 <= d <= 1.0:
            warn(f"Pen.setInkColor(): colour {rgb:#x} or density {d} out of range for '{self._name}'; ignored")
            return
        fields = self._record.node.fields
        fields["inkColor"] = ((rgb >> 16 & 0xFF) / 255.0, (rgb >> 8 & 0xFF) / 255.0, (rgb & 0xFF) / 255.0)
        fields["inkDensity"] = d
