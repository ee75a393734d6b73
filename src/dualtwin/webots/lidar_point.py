"""Webots' ``LidarPoint``: one point of a Lidar's point cloud (webots-devices.md §3.3; Webots' own
``lidar_point.py``), a plain value that crosses to a controller process by value."""

from __future__ import annotations

from typing import Any

__all__ = ["LidarPoint"]


class LidarPoint:
    """One point of a lidar point cloud (lidar frame: x forward, y left, z up), with Webots' plain attributes
    ``x``, ``y``, ``z``, ``layer`` and ``time``. Webots builds it from the C struct array and an offset
    (``LidarPoint(data, offset)``); here ``data`` is a sequence of ``(x, y, z, layer, time)`` records."""

    x: float
    y: float
    z: float
    layer: int
    time: float

    def __init__(self, data: Any, offset: Any) -> None:
        x, y, z, layer, time = data[int(offset)]
        self.x, self.y, self.z = float(x), float(y), float(z)
        self.layer, self.time = int(layer), float(time)

    # ``layer_id`` is the C field name
    @property
    def layer_id(self) -> int:
        return self.layer

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LidarPoint) and (self.x, self.y, self.z, self.layer, self.time) == (
            other.x, other.y, other.z, other.layer, other.time)  # fmt: skip

    def __hash__(self) -> int:
        return hash((self.x, self.y, self.z, self.layer, self.time))

    def __repr__(self) -> str:
        return f"LidarPoint(x={self.x}, y={self.y}, z={self.z}, layer={self.layer}, time={self.time})"
