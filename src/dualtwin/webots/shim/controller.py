"""Stand-in for Webots' ``controller`` Python module.

:func:`dualtwin.webots.runner.run_world` puts this directory first on ``sys.path`` so unchanged Webots
scripts doing ``from controller import Robot, Supervisor, Motor, ...`` get the Webots-twin API, bound to
the runner's current simulation.
"""

from __future__ import annotations

from dualtwin.webots.controller import (
    GPS,
    Accelerometer,
    Camera,
    ContactPoint,
    Device,
    Display,
    DistanceSensor,
    Emitter,
    Field,
    Gyro,
    ImageRef,
    InertialUnit,
    Keyboard,
    Lidar,
    LidarPoint,
    Motor,
    Node,
    PositionSensor,
    RangeFinder,
    Receiver,
    Robot,
    Supervisor,
    TouchSensor,
)

__all__ = [
    "GPS",
    "Accelerometer",
    "Camera",
    "ContactPoint",
    "Device",
    "Display",
    "DistanceSensor",
    "Emitter",
    "Field",
    "Gyro",
    "ImageRef",
    "InertialUnit",
    "Keyboard",
    "Lidar",
    "LidarPoint",
    "Motor",
    "Node",
    "PositionSensor",
    "RangeFinder",
    "Receiver",
    "Robot",
    "Supervisor",
    "TouchSensor",
]
