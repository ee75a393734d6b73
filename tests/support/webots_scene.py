"""Hand-built Webots scene trees for physics tests (independent of the parser).

Each factory fills the Webots R2023b defaults of the fields the physics layer reads, mirroring what the
parser produces after default filling.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any

from dualtwin.webots.nodes import Node, World

_DEFAULTS: dict[str, dict[str, Any]] = {
    "WorldInfo": {
        "gravity": 9.81,
        "CFM": 0.00001,
        "ERP": 0.2,
        "basicTimeStep": 32.0,
        "physicsDisableTime": 1.0,
        "physicsDisableLinearThreshold": 0.01,
        "physicsDisableAngularThreshold": 0.01,
        "defaultDamping": None,
        "coordinateSystem": "ENU",
        "randomSeed": 0,
        "contactProperties": [],
    },
    "Solid": {
        "translation": (0.0, 0.0, 0.0),
        "rotation": (0.0, 0.0, 1.0, 0.0),
        "children": [],
        "name": "solid",
        "model": "",
        "description": "",
        "contactMaterial": "default",
        "immersionProperties": [],
        "boundingObject": None,
        "physics": None,
        "locked": False,
        "linearVelocity": (0.0, 0.0, 0.0),
        "angularVelocity": (0.0, 0.0, 0.0),
    },
    "Physics": {"density": 1000.0, "mass": -1.0, "centerOfMass": [], "inertiaMatrix": [], "damping": None},
    "Damping": {"linear": 0.2, "angular": 0.2},
    "Pose": {"translation": (0.0, 0.0, 0.0), "rotation": (0.0, 0.0, 1.0, 0.0), "children": []},
    "Group": {"children": []},
    "Shape": {"appearance": None, "geometry": None, "castShadows": True, "isPickable": True},
    "Box": {"size": (2.0, 2.0, 2.0)},
    "Sphere": {"radius": 1.0, "subdivision": 1, "ico": True},
    "Cylinder": {"radius": 1.0, "height": 2.0, "bottom": True, "side": True, "top": True, "subdivision": 36},
    "Capsule": {"radius": 1.0, "height": 2.0, "bottom": True, "side": True, "top": True, "subdivision": 12},
    "Plane": {"size": (1.0, 1.0)},
    "HingeJoint": {"jointParameters": None, "device": [], "endPoint": None},
    "SliderJoint": {"jointParameters": None, "device": [], "endPoint": None},
    "Hinge2Joint": {
        "jointParameters": None,
        "jointParameters2": None,
        "device": [],
        "device2": [],
        "endPoint": None,
    },
    "BallJoint": {"jointParameters": None, "device": [], "endPoint": None},
    "HingeJointParameters": {
        "position": 0.0,
        "axis": (1.0, 0.0, 0.0),
        "anchor": (0.0, 0.0, 0.0),
        "minStop": 0.0,
        "maxStop": 0.0,
        "springConstant": 0.0,
        "dampingConstant": 0.0,
        "staticFriction": 0.0,
        "suspensionSpringConstant": 0.0,
        "suspensionDampingConstant": 0.0,
        "suspensionAxis": (1.0, 0.0, 0.0),
        "stopERP": -1.0,
        "stopCFM": -1.0,
    },
    "JointParameters": {
        "position": 0.0,
        "axis": (0.0, 0.0, 1.0),
        "minStop": 0.0,
        "maxStop": 0.0,
        "springConstant": 0.0,
        "dampingConstant": 0.0,
        "staticFriction": 0.0,
    },
    "RotationalMotor": {
        "name": "rotational motor",
        "acceleration": -1.0,
        "consumptionFactor": 10.0,
        "controlPID": (10.0, 0.0, 0.0),
        "maxVelocity": 10.0,
        "minPosition": 0.0,
        "maxPosition": 0.0,
        "maxTorque": 10.0,
        "multiplier": 1.0,
        "sound": "",
        "muscles": [],
    },
    "LinearMotor": {
        "name": "linear motor",
        "acceleration": -1.0,
        "consumptionFactor": 10.0,
        "controlPID": (10.0, 0.0, 0.0),
        "maxVelocity": 10.0,
        "minPosition": 0.0,
        "maxPosition": 0.0,
        "maxForce": 10.0,
        "multiplier": 1.0,
        "sound": "",
        "muscles": [],
    },
    "PositionSensor": {"name": "position sensor", "noise": 0.0, "resolution": -1.0},
    "ContactProperties": {
        "material1": "default",
        "material2": "default",
        "coulombFriction": [1.0],
        "frictionRotation": (0.0, 0.0),
        "rollingFriction": (0.0, 0.0, 0.0),
        "bounce": 0.5,
        "bounceVelocity": 0.01,
        "forceDependentSlip": [0.0],
        "softERP": 0.2,
        "softCFM": 0.001,
        "maxContactJoints": 10,
    },
}
_DEFAULTS["Robot"] = {
    **_DEFAULTS["Solid"],
    "name": "robot",
    "controller": "<generic>",
    "controllerArgs": [],
    "customData": "",
    "supervisor": False,
    "synchronization": True,
    "selfCollision": False,
}
for _t in ("GPS", "Gyro", "InertialUnit", "Accelerometer"):
    _DEFAULTS[_t] = {**_DEFAULTS["Solid"], "name": _t.lower()}
_DEFAULTS["InertialUnit"]["name"] = "inertial unit"
_DEFAULTS["Accelerometer"]["name"] = "accelerometer"


def node(type_name: str, def_name: str | None = None, **fields: Any) -> Node:
    """A node of ``type_name`` with Webots defaults, overridden by ``fields``."""
    values = dict(_DEFAULTS.get(type_name, {}))
    for key, value in fields.items():
        if isinstance(value, list):
            value = list(value)
        values[key] = value
    return Node(type_name, values, def_name=def_name)


def world(*nodes: Node, **info: Any) -> World:
    """A World with a WorldInfo (fields from ``info``) followed by ``nodes``."""
    return World(path="<test>", header="#VRML_SIM R2023b utf8", nodes=[node("WorldInfo", **info), *nodes])


def floor(material: str = "default") -> Node:
    """Static infinite ground plane at z = 0 (like Webots' Floor)."""
    return node("Solid", name="floor", boundingObject=node("Plane"), contactMaterial=material)


def box_solid(size: tuple[float, float, float], translation=(0.0, 0.0, 0.0), **kw: Any) -> Node:
    physics = kw.pop("physics", node("Physics"))
    return node(
        "Solid", translation=tuple(translation), boundingObject=node("Box", size=size), physics=physics, **kw
    )


def cart_pole(pole_angle: float = 0.0, time_step: float = 16.0) -> World:
    """A box on 4 motorised wheel cylinders on a plane, with a passive hinged pole (benchmark world)."""
    wheels = []
    for i, (x, y) in enumerate(((0.15, 0.12), (0.15, -0.12), (-0.15, 0.12), (-0.15, -0.12))):
        wheel = node(
            "Solid",
            name=f"wheel{i}",
            translation=(x, y, -0.03),
            rotation=(1.0, 0.0, 0.0, 1.5708),
            boundingObject=node("Cylinder", radius=0.05, height=0.03),
            physics=node("Physics", density=-1.0, mass=0.2),
        )
        wheels.append(
            node(
                "HingeJoint",
                jointParameters=node("HingeJointParameters", axis=(0.0, 1.0, 0.0), anchor=(x, y, -0.03)),
                device=[
                    node("RotationalMotor", name=f"wheel{i}"),
                    node("PositionSensor", name=f"wheel{i} sensor"),
                ],
                endPoint=wheel,
            )
        )
    s, c = math.sin(pole_angle), math.cos(pole_angle)
    pole = node(
        "HingeJoint",
        jointParameters=node(
            "HingeJointParameters", axis=(0.0, 1.0, 0.0), anchor=(0.0, 0.0, 0.04), position=pole_angle
        ),
        device=[node("PositionSensor", name="pole sensor")],
        endPoint=node(
            "Solid",
            name="pole",
            # the endPoint pose in a file is the pose *at* the joint position (spec §4.1)
            translation=(0.25 * s, 0.0, 0.04 + 0.25 * c),
            rotation=(0.0, 1.0, 0.0, pole_angle),
            boundingObject=node("Box", size=(0.02, 0.02, 0.5)),
            physics=node("Physics", density=-1.0, mass=0.1),
        ),
    )
    robot = node(
        "Robot",
        "CART",
        name="cart",
        translation=(0.0, 0.0, 0.08),
        children=[*wheels, pole],
        boundingObject=node("Box", size=(0.4, 0.2, 0.08)),
        physics=node("Physics", density=-1.0, mass=2.0),
        controller="<none>",
        supervisor=True,
    )
    return world(floor(), robot, basicTimeStep=time_step)


def write_controllers(root: Path, scripts: dict[str, str]) -> None:
    """A Webots project's controllers: each script (dedented) as ``root/controllers/NAME/NAME.py``."""
    for name, script in scripts.items():
        folder = root / "controllers" / name
        folder.mkdir(parents=True)
        (folder / f"{name}.py").write_text(textwrap.dedent(script))
