"""What ``tests/webots/test_api_return_types*.py`` share: the type check of a result against Webots' documented
return type, and one rich world (a supervisor robot with one of each device, a PROTO with the field types no base
node has, scenery for the sensors to see), built, enabled and stepped.

A return type is written as Python writes types: ``float``, ``int``, ``bool``, ``str``, ``bytes``, ``None``,
``list[float]``, ``list[list[float]]``, ``tuple[float, ...]``, an API class (``Node``), or a union of those
(``Node | None``). :func:`conforms` checks ``type(value)`` exactly (``True`` is not an ``int``, a NumPy float64 is
not a ``float``, a tuple is not a list) and every element of a container; an abstract class (``Device``) takes any
of its subclasses that the ``controller`` module exports.
"""

from __future__ import annotations

import types
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, get_args, get_origin

from dualtwin.webots import controller, load_world_text
from dualtwin.webots.controller import Device, Field, Node, Sensor, Supervisor
from dualtwin.webots.physics import Simulation

__all__ = ["RichWorld", "conforms", "describe", "spec_text"]

ABSTRACT = (Device, Sensor)

#: a PROTO for the field types no base node has (MFBool, MFRotation)
FLAGS_PROTO = """#VRML_SIM R2023b utf8
PROTO Flags [
  field SFVec3f    translation 0 5 0.5
  field MFBool     flags [ TRUE FALSE ]
  field MFRotation turns [ 0 0 1 0, 0 1 0 1.5 ]
]
{
  Solid { translation IS translation children [ DEF INNER Pose { } ] name "flags" }
}
"""

MOTION = "#WEBOTS_MOTION,V1.0,rm\n00:00:000,Pose1,0\n00:00:080,Pose2,0.2\n"

WORLD = """#VRML_SIM R2023b utf8
EXTERNPROTO "Flags.proto"
WorldInfo { basicTimeStep 8 }
DirectionalLight { direction 0 0 -1 }
PointLight { location 0 0 2 }
DEF FLOOR Solid { name "floor" boundingObject Plane { size 20 20 } }
DEF BOX Solid {
  translation 1 0 0.1 name "box" model "crate"
  recognitionColors [ 1 0 0, 0 0 1 ] radarCrossSection 1
  children [ Shape { appearance PBRAppearance { baseColor 1 0 0 roughness 1 metalness 0 } geometry Box { size 0.2 0.2 0.2 } } ]
  boundingObject Box { size 0.2 0.2 0.2 } physics Physics { density -1 mass 1 }
}
DEF SCENERY Solid {
  translation 0 -5 0 name "scenery"
  children [
    Shape { geometry ElevationGrid { xDimension 2 yDimension 2 xSpacing 1 ySpacing 1 height [ 0 0.1 0.2 0.3 ] } }
    Shape { geometry IndexedFaceSet {
      coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] }
      texCoord TextureCoordinate { point [ 0 0, 1 0, 0 1 ] }
      coordIndex [ 0 1 2 -1 ]
    } }
  ]
}
DEF FLAGS Flags { }
DEF TALKER Robot {
  translation 0 2 0.5 name "talker"
  children [ Emitter { name "tx" } ]
  controller "<none>"
}
DEF ROBOT Robot {
  translation 0 0 0.1 name "rich" model "tester" customData "data"
  controllerArgs [ "a" "b" ]
  battery [ 100 100 10 ]
  children [
    Accelerometer { name "acc" }
    Altimeter { name "alt" }
    Camera { name "cam" width 16 height 12 recognition Recognition { segmentation TRUE } }
    Compass { name "compass" }
    Connector { name "con" }
    Display { name "display" width 8 height 6 }
    DistanceSensor { name "ds" lookupTable [ 0 0 0, 2 1000 0 ] }
    Emitter { name "emitter" }
    Receiver { name "rx" }
    GPS { name "gps" }
    Gyro { name "gyro" }
    InertialUnit { name "imu" }
    LED { name "led" }
    Lidar { name "lidar" horizontalResolution 8 fieldOfView 1 numberOfLayers 2 verticalFieldOfView 0.25 }
    LightSensor { name "light" }
    Radar { name "radar" minRange 0.1 maxRange 10 }
    RangeFinder { name "range" width 8 height 6 }
    Speaker { name "speaker" }
    TouchSensor { name "touch" translation 0 0.5 0 boundingObject Sphere { radius 0.05 } }
    VacuumGripper { name "cup" translation 0 -0.5 0 boundingObject Box { size 0.1 0.1 0.02 } }
    Pen { name "pen" }
    HingeJoint {
      jointParameters HingeJointParameters { axis 0 0 1 anchor 0 0 1 }
      device [ RotationalMotor { name "rm" maxTorque 10 } PositionSensor { name "ps" } Brake { name "brake" } ]
      endPoint Solid {
        translation 0.3 0 1 name "arm"
        boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }
      }
    }
    SliderJoint {
      jointParameters JointParameters { axis 1 0 0 }
      device [ LinearMotor { name "lm" maxForce 10 } PositionSensor { name "lps" } ]
      endPoint Solid {
        translation 0 0 2 name "slider"
        boundingObject Sphere { radius 0.05 } physics Physics { density -1 mass 1 }
      }
    }
  ]
  controller "<extern>"
  supervisor TRUE
}
"""

STEP = 8
SENSORS = ("acc", "alt", "cam", "compass", "ds", "rx", "gps", "gyro", "imu", "lidar", "light", "radar", "range",
           "touch", "ps", "lps")


@dataclass
class RichWorld:
    """The rich world, enabled and stepped: the supervisor, its devices by name, nodes and one field per type."""

    folder: Path
    sim: Simulation
    sup: Supervisor
    dev: dict[str, Any]
    nodes: dict[str, Node]
    fields: dict[str, Field] = field(default_factory=dict)
    talker: Any = None

    @classmethod
    def build(cls, folder: Path) -> RichWorld:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "Flags.proto").write_text(FLAGS_PROTO)
        (folder / "turn.motion").write_text(MOTION)
        path = folder / "rich.wbt"
        path.write_text(WORLD)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sim = Simulation(load_world_text(WORLD, path))
        from dualtwin.webots.controller import Robot, Runtime

        runtime = Runtime(sim)
        talker = Robot(runtime=runtime, robot_node=sim.robots[0].node)
        talker.cleanup()  # its devices work, only the rich robot's controller steps
        sup = Supervisor(runtime=runtime, robot_node=sim.robots[1].node)
        dev = {sup.getDeviceByIndex(i).getName(): sup.getDeviceByIndex(i) for i in range(sup.getNumberOfDevices())}
        nodes = {name: sup.getFromDef(name) for name in ("BOX", "FLOOR", "SCENERY", "FLAGS", "ROBOT", "TALKER")}
        world = cls(folder, sim, sup, dev, nodes, talker=talker)
        world._fields()
        world._enable()
        for _ in range(3):
            sup.step(STEP)
        return world

    def _fields(self) -> None:
        box, scenery, robot, flags = (self.nodes[n] for n in ("BOX", "SCENERY", "ROBOT", "FLAGS"))
        shapes = scenery.getField("children")
        grid = shapes.getMFNode(0).getField("geometry").getSFNode()
        faces = shapes.getMFNode(1).getField("geometry").getSFNode()
        floor_plane = self.nodes["FLOOR"].getField("boundingObject").getSFNode()
        appearance = box.getField("children").getMFNode(0).getField("appearance").getSFNode()
        self.fields = {
            "SFBool": robot.getField("supervisor"),
            "SFInt32": self.sup.getFromDevice(self.dev["cam"]._tag).getField("width"),
            "SFFloat": box.getField("physics").getSFNode().getField("mass"),
            "SFVec2f": floor_plane.getField("size"),
            "SFVec3f": box.getField("translation"),
            "SFRotation": box.getField("rotation"),
            "SFColor": appearance.getField("baseColor"),
            "SFString": box.getField("name"),
            "SFNode": box.getField("boundingObject"),
            "MFBool": flags.getField("flags"),
            "MFInt32": faces.getField("coordIndex"),
            "MFFloat": grid.getField("height"),
            "MFVec2f": faces.getField("texCoord").getSFNode().getField("point"),
            "MFVec3f": faces.getField("coord").getSFNode().getField("point"),
            "MFRotation": flags.getField("turns"),
            "MFColor": box.getField("recognitionColors"),
            "MFString": robot.getField("controllerArgs"),
            "MFNode": scenery.getField("children"),
        }

    def _enable(self) -> None:
        for name in SENSORS:
            self.dev[name].enable(STEP)
        self.dev["lidar"].enablePointCloud()
        self.dev["cam"].recognitionEnable(STEP)
        self.dev["cam"].enableRecognitionSegmentation()
        self.dev["con"].enablePresence(STEP)
        self.dev["cup"].enablePresence(STEP)
        for motor in ("rm", "lm"):
            self.dev[motor].enableForceFeedback(STEP)
            self.dev[motor].enableTorqueFeedback(STEP)
        self.sup.batterySensorEnable(STEP)
        self.sup.getKeyboard().enable(STEP)
        self.sup.getMouse().enable(STEP)
        self.sup.getJoystick().enable(STEP)
        self.nodes["BOX"].enableContactPointsTracking(STEP)
        self.talker.getDevice("tx").send([1.5, 2.5])  # 16 bytes: two doubles, four ints, sixteen bools

    def close(self) -> None:
        self.sim.close()


def conforms(value: Any, spec: Any) -> bool:
    """Whether ``value`` is exactly of the return type ``spec`` (see the module docstring)."""
    if spec is None or spec is type(None):
        return value is None
    if isinstance(spec, types.UnionType):
        return any(conforms(value, option) for option in get_args(spec))
    origin = get_origin(spec)
    if origin is not None:
        if type(value) is not origin:
            return False
        (item, *rest) = get_args(spec)
        return all(conforms(v, item) for v in value) if not rest or rest == [Ellipsis] else False
    if spec in ABSTRACT:  # one of the API's own device classes (not a private stand-in)
        return isinstance(value, spec) and getattr(controller, type(value).__name__, None) is type(value)
    return type(value) is spec


def spec_text(spec: Any) -> str:
    if spec is None:
        return "None"
    return spec.__name__ if isinstance(spec, type) and get_origin(spec) is None else str(spec).replace(
        "dualtwin.webots.", "")


def describe(value: Any, depth: int = 0) -> str:
    """The type of ``value`` written like a spec, with the element types of a container (``list[float64]``)."""
    name = type(value).__name__
    if isinstance(value, (list, tuple)) and depth < 3:
        inner = sorted({describe(v, depth + 1) for v in value})
        return f"{name}[{' | '.join(inner) if inner else ''}]"
    return f"{name} ({value!r})" if depth == 0 and not isinstance(value, (bytes, bytearray)) else name
