"""Webots' ``CameraRecognitionObject``: one object a Camera's Recognition node reports.

A plain record, as in Webots (there a ctypes structure): the object's node ``id``, its ``position`` and
``orientation`` (axis-angle) in the camera frame, its ``size`` (m), where it is on the image (``position_on_image``,
``size_on_image`` in pixels), and its recognition colours (``number_of_colors``, ``colors``: 3 floats each).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["CameraRecognitionObject"]


@dataclass(eq=False)
class CameraRecognitionObject:
    id: int = -1
    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    orientation: list[float] = field(default_factory=lambda: [0.0, 0.0, 1.0, 0.0])
    size: list[float] = field(default_factory=lambda: [0.0, 0.0])
    position_on_image: list[int] = field(default_factory=lambda: [0, 0])
    size_on_image: list[int] = field(default_factory=lambda: [0, 0])
    number_of_colors: int = 0
    colors: list[float] = field(default_factory=list)
    _model: str = ""

    def getId(self) -> int:
        return self.id

    def getPosition(self) -> list[float]:
        return list(self.position)

    def getOrientation(self) -> list[float]:
        return list(self.orientation)

    def getSize(self) -> list[float]:
        return list(self.size)

    def getPositionOnImage(self) -> list[int]:
        return list(self.position_on_image)

    def getSizeOnImage(self) -> list[int]:
        return list(self.size_on_image)

    def getNumberOfColors(self) -> int:
        return self.number_of_colors

    def getColors(self) -> list[float]:
        return list(self.colors)

    def getModel(self) -> str:
        return self._model

    model = property(lambda self: self.getModel())
