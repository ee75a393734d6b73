"""Webots' Python controller API over a :class:`~dualtwin.webots.physics.Simulation`: what ``from controller import X``
gives an unchanged Webots script (the runner's shim re-exports this module).

Two ways to create the API:

* explicitly on an already built simulation::

      sim = Simulation(load_world(path))
      sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
      while sup.step(32) != -1: ...

* unchanged Webots scripts (``from controller import Supervisor``; ``Supervisor()``) pick the
  module-level *current runtime* installed by :mod:`dualtwin.webots.runner` (or by
  :func:`set_current_runtime`).

Several controllers may share one :class:`Runtime`: the simulation then advances only once every registered
controller has asked for the next step (Webots' synchronisation).

Where each part lives: ``Robot`` (:mod:`.robot`) and ``Supervisor`` (:mod:`.supervisor`) over the runtime state of
:mod:`.robot_link`; ``Node``/``ContactPoint`` (:mod:`.scene_api`) and ``Field`` (:mod:`.field_api`); the devices in
their own modules; the classes Webots needs its GUI for (mouse, joystick, speaker, pen, skin) answer what Webots
answers without one (each module says what). ``tests/webots/test_api_surface.py`` holds the whole surface to
Webots R2023b's, name for name.

Numeric arguments go through :mod:`.api_args`: scalars and one-element arrays of any numeric type are taken,
anything else is a ``TypeError`` at the call naming the method.
"""

from __future__ import annotations

from dualtwin.webots.altimeter import Altimeter
from dualtwin.webots.ansi_codes import AnsiCodes
from dualtwin.webots.camera import Camera
from dualtwin.webots.compass import Compass
from dualtwin.webots.connector import Connector
from dualtwin.webots.device_base import Device, Sensor
from dualtwin.webots.devices import GPS, Accelerometer, Brake, Gyro, InertialUnit, Motor, PositionSensor
from dualtwin.webots.display import Display
from dualtwin.webots.field_api import Field
from dualtwin.webots.gui_devices import Skin, Speaker
from dualtwin.webots.joystick import Joystick
from dualtwin.webots.keyboard import Keyboard
from dualtwin.webots.led import LED
from dualtwin.webots.light_sensor import LightSensor
from dualtwin.webots.motion import Motion
from dualtwin.webots.mouse import Mouse, MouseState
from dualtwin.webots.pen import Pen
from dualtwin.webots.physics import SimulationUnstable
from dualtwin.webots.radar import Radar, RadarTarget
from dualtwin.webots.radio import Emitter, Receiver
from dualtwin.webots.ranging import DistanceSensor, Lidar, LidarPoint, RangeFinder
from dualtwin.webots.recognition import CameraRecognitionObject
from dualtwin.webots.robot import Robot
from dualtwin.webots.runtime import ControllerStopped, Runtime, current_runtime, set_current_runtime
from dualtwin.webots.scene_api import ContactPoint, Node
from dualtwin.webots.supervisor import Supervisor
from dualtwin.webots.touch import TouchSensor
from dualtwin.webots.vacuum_gripper import VacuumGripper

__all__ = [
    "GPS",
    "LED",
    "Accelerometer",
    "Altimeter",
    "AnsiCodes",
    "Brake",
    "Camera",
    "CameraRecognitionObject",
    "Compass",
    "Connector",
    "ContactPoint",
    "ControllerStopped",
    "Device",
    "Display",
    "DistanceSensor",
    "Emitter",
    "Field",
    "Gyro",
    "InertialUnit",
    "Joystick",
    "Keyboard",
    "Lidar",
    "LidarPoint",
    "LightSensor",
    "Motion",
    "Motor",
    "Mouse",
    "MouseState",
    "Node",
    "Pen",
    "PositionSensor",
    "Radar",
    "RadarTarget",
    "RangeFinder",
    "Receiver",
    "Robot",
    "Runtime",
    "Sensor",
    "SimulationUnstable",
    "Skin",
    "Speaker",
    "Supervisor",
    "TouchSensor",
    "VacuumGripper",
    "current_runtime",
    "set_current_runtime",
]
