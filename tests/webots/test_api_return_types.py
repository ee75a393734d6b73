"""What Webots R2023b's Python controller API returns, call by call: the exact type of every result.

``RETURNS`` below is our own encoding of the return types Webots' Python ``controller`` package documents (its
wrapper over libController, R2023b): per class, method -> type. Results are plain Python values, never NumPy; a C
bool the wrapper does not compare with 0 comes back as an ``int`` (``Field.getSFBool``, ``Connector.getPresence``,
``Supervisor.animation*Recording``); where the C value is a bool the wrapper converts, a ``bool``.
``tests/webots/test_api_surface.py`` holds the names and signatures; this file holds what the calls return.

Every method with a return type that can be called headless with simple arguments is one test item, called on the
devices, nodes and fields of one rich world (``tests/support/api_returns.py``: a supervisor robot with one of each
device, enabled and stepped so every reading has arrived). The check is exact: ``type(result)`` must be the type
written here (``True`` is not an ``int``, a NumPy float64 is not a ``float``, a tuple is not a list), and so must
every element of a list. Commands (their type is ``None``) run on a world of their own, so that they do not change
what the other items read.

Not called: ``__init__`` methods; R2024a-only names (``Proto``, ``Node.getBaseNodeField*``,
``Field.getActualField``); ``LidarPoint``, ``RadarTarget``, ``MouseState`` (no method but ``__init__``); ``Skin``
(no Skin node exists headless). Where Webots' wrapper hands out raw ctypes memory (``TouchSensor.getValues``, a
``pointer``; ``CameraRecognitionObject.getPosition`` and the other getters, ``c_double * n`` / ``c_int * n``
arrays), the type here is the list of the same items: a ctypes pointer cannot cross to a controller process, and
indexing, the only use Webots' pointer allows, works the same on a list.

``test_types_cross_a_controller_process`` checks a handful of the same calls from a controller run as its own
process, where results cross a pickle channel.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from dualtwin.webots.controller import (
    Brake,
    CameraRecognitionObject,
    ContactPoint,
    Device,
    Display,
    Field,
    Joystick,
    Keyboard,
    LidarPoint,
    Motion,
    Motor,
    Mouse,
    MouseState,
    Node,
    PositionSensor,
    RadarTarget,
    Robot,
    Sensor,
)
from dualtwin.webots.runner import run_world
from tests.support.api_returns import RichWorld, conforms, describe, spec_text

LF = list[float]

# ------------------------------------------------------------------ what Webots returns (R2023b)

RETURNS: dict[str, dict[str, Any]] = {
    "Robot": {
        "getDevice": Device | None, "getDeviceByIndex": Device, "getNumberOfDevices": int, "getKeyboard": Keyboard,
        "getMouse": Mouse, "getJoystick": Joystick, "getBasicTimeStep": float, "getTime": float, "getName": str,
        "getModel": str, "getCustomData": str, "setCustomData": None, "getProjectPath": str, "getWorldPath": str,
        "getSupervisor": bool, "getSynchronization": bool, "getUrdf": str, "wwiSendText": None,
        "wwiReceiveText": str | None, "step": int, "stepBegin": int, "stepEnd": int, "waitForUserInputEvent": int,
        "batterySensorEnable": None, "batterySensorDisable": None, "batterySensorGetSamplingPeriod": int,
        "batterySensorGetValue": float, "getMode": int, "setMode": None,
    },
    "Supervisor": {
        "getRoot": Node, "getSelf": Node, "getFromDef": Node | None, "getFromId": Node | None,
        "getFromDevice": Node | None, "getSelected": Node | None, "setLabel": None, "simulationQuit": None,
        "simulationSetMode": None, "simulationGetMode": int, "simulationReset": None,
        "simulationResetPhysics": None, "worldLoad": None, "worldSave": int, "worldReload": None,
        "exportImage": None, "movieStartRecording": None, "movieStopRecording": None, "movieIsReady": bool,
        "movieFailed": bool, "animationStartRecording": int, "animationStopRecording": int,
        "virtualRealityHeadsetIsUsed": bool, "virtualRealityHeadsetGetPosition": LF,
        "virtualRealityHeadsetGetOrientation": LF,
    },
    "Node": {
        "getDef": str, "getId": int, "getParentNode": Node | None, "isProto": bool, "getFromProtoDef": Node | None,
        "getType": int, "getTypeName": str, "getBaseTypeName": str, "remove": None, "exportString": str,
        "getField": Field | None, "getFieldByIndex": Field | None, "getNumberOfFields": int,
        "getProtoField": Field | None, "getProtoFieldByIndex": Field | None, "getPosition": LF,
        "getOrientation": LF, "getPose": LF, "enablePoseTracking": None, "disablePoseTracking": None,
        "getCenterOfMass": LF, "getContactPoints": list[ContactPoint], "enableContactPointsTracking": None,
        "disableContactPointsTracking": None, "getStaticBalance": bool, "getVelocity": LF, "setVelocity": None,
        "saveState": None, "loadState": None, "resetPhysics": None, "setJointPosition": None,
        "restartController": None, "moveViewpoint": None, "setVisibility": None, "addForce": None,
        "addForceWithOffset": None, "addTorque": None,
    },
    "ContactPoint": {"getPoint": LF, "getNodeId": int},
    "Field": {
        "getName": str, "getType": int, "getTypeName": str, "getCount": int, "enableSFTracking": None,
        "disableSFTracking": None,
        "getSFBool": int,  # the C bool as an int (0/1)
        "getSFInt32": int, "getSFFloat": float, "getSFVec2f": LF, "getSFVec3f": LF, "getSFRotation": LF,
        "getSFColor": LF, "getSFString": str, "getSFNode": Node | None,
        "getMFBool": bool, "getMFInt32": int, "getMFFloat": float, "getMFVec2f": LF, "getMFVec3f": LF,
        "getMFRotation": LF, "getMFColor": LF, "getMFString": str, "getMFNode": Node | None,
        **{f"set{k}{t}": None for k in ("SF", "MF") for t in
           ("Bool", "Int32", "Float", "Vec2f", "Vec3f", "Rotation", "Color", "String")},
        **{f"insertMF{t}": None for t in ("Bool", "Int32", "Float", "Vec2f", "Vec3f", "Rotation", "Color", "String")},
        "removeMF": None, "removeSF": None, "importMFNodeFromString": None, "importSFNodeFromString": None,
    },
    "Device": {"getName": str, "getModel": str, "getNodeType": int},
    "Sensor": {"enable": None, "disable": None, "getSamplingPeriod": int},
    "Motor": {
        "setPosition": None, "setVelocity": None, "setAcceleration": None, "setAvailableForce": None,
        "setAvailableTorque": None, "setControlPID": None, "setForce": None, "setTorque": None,
        "getTargetPosition": float, "getMinPosition": float, "getMaxPosition": float, "getVelocity": float,
        "getMaxVelocity": float, "getAcceleration": float, "getAvailableForce": float, "getMaxForce": float,
        "getAvailableTorque": float, "getMaxTorque": float, "getMultiplier": float, "enableForceFeedback": None,
        "disableForceFeedback": None, "getForceFeedbackSamplingPeriod": int, "getForceFeedback": float,
        "enableTorqueFeedback": None, "disableTorqueFeedback": None, "getTorqueFeedbackSamplingPeriod": int,
        "getTorqueFeedback": float, "getType": int, "getBrake": Brake | None,
        "getPositionSensor": PositionSensor | None,
    },
    "PositionSensor": {"getValue": float, "getType": int, "getBrake": Brake | None, "getMotor": Motor | None},
    "Brake": {
        "setDampingConstant": None, "getType": int, "getMotor": Motor | None,
        "getPositionSensor": PositionSensor | None,
    },
    "Keyboard": {
        "enable": None, "disable": None, "getSamplingPeriod": int, "getKey": int, "getKeyCode": int, "get_key": str,
    },
    "Connector": {
        "enablePresence": None, "disablePresence": None,
        "getPresence": int,  # the C int as is (1 or 0), not a bool
        "getPresenceSamplingPeriod": int, "isLocked": bool, "lock": None, "unlock": None,
    },
    "DistanceSensor": {
        "getValue": float, "getMaxValue": float, "getMinValue": float, "getAperture": float, "getLookupTable": LF,
        "getType": int,
    },
    "Lidar": {
        "getRangeImage": LF, "getRangeImageArray": list[LF], "getLayerRangeImage": LF, "enablePointCloud": None,
        "disablePointCloud": None, "isPointCloudEnabled": bool, "getPointCloud": list[LidarPoint],
        "getLayerPointCloud": list[LidarPoint], "getNumberOfPoints": int, "getFrequency": float,
        "setFrequency": None, "getMinFrequency": float, "getMaxFrequency": float, "getFov": float,
        "getVerticalFov": float, "getHorizontalResolution": int, "getNumberOfLayers": int, "getMinRange": float,
        "getMaxRange": float,
    },
    "Camera": {
        "getImage": bytes, "getImageArray": list[list[list[int]]], "imageGetRed": int, "imageGetGreen": int,
        "imageGetBlue": int, "imageGetGray": float, "saveImage": int, "getWidth": int, "getHeight": int,
        "getFov": float, "setFov": None, "getMinFov": float, "getMaxFov": float, "getExposure": float,
        "setExposure": None, "getFocalLength": float, "getFocalDistance": float, "setFocalDistance": None,
        "getMinFocalDistance": float, "getMaxFocalDistance": float, "getNear": float, "hasRecognition": bool,
        "recognitionEnable": None, "recognitionDisable": None, "getRecognitionSamplingPeriod": int,
        "getRecognitionNumberOfObjects": int, "getRecognitionObjects": list[CameraRecognitionObject],
        "hasRecognitionSegmentation": bool, "enableRecognitionSegmentation": None,
        "disableRecognitionSegmentation": None, "isRecognitionSegmentationEnabled": bool,
        "getRecognitionSegmentationImage": bytes, "getRecognitionSegmentationImageArray": list[list[list[int]]],
        "saveRecognitionSegmentationImage": int,
    },
    "CameraRecognitionObject": {
        # Webots: c_double * 3, * 4, * 2, c_int * 2 (ctypes arrays) and a pointer to the colours
        "getId": int, "getPosition": LF, "getOrientation": LF, "getSize": LF, "getPositionOnImage": list[int],
        "getSizeOnImage": list[int], "getNumberOfColors": int, "getColors": LF, "getModel": str,
    },
    "TouchSensor": {
        "getValue": float,
        "getValues": LF,  # Webots' wrapper: a raw ctypes pointer to the 3 doubles (see the module docstring)
        "getLookupTable": LF, "getType": int,
    },
    "Emitter": {
        "send": None, "getChannel": int, "setChannel": None, "getRange": float, "setRange": None,
        "getBufferSize": int,
    },
    "Receiver": {
        "getQueueLength": int, "nextPacket": None, "getBytes": bytes, "getString": str, "getData": str,
        "getDataSize": int,
        # struct.unpack of the packet: tuples
        "getFloats": tuple[float, ...], "getInts": tuple[int, ...], "getBools": tuple[bool, ...],
        "getSignalStrength": float, "getEmitterDirection": LF, "getChannel": int, "setChannel": None,
    },
    "GPS": {
        "getValues": LF, "getSpeed": float, "getSpeedVector": LF, "getCoordinateSystem": int,
        "convertToDegreesMinutesSeconds": str,
    },
    "Gyro": {"getValues": LF, "getLookupTable": LF},
    "Accelerometer": {"getValues": LF, "getLookupTable": LF},
    "InertialUnit": {"getRollPitchYaw": LF, "getQuaternion": LF, "getNoise": float},
    "Compass": {"getValues": LF, "getLookupTable": LF},
    "RangeFinder": {
        "getRangeImage": LF, "getRangeImageArray": list[LF], "rangeImageGetDepth": float, "saveImage": int,
        "getFov": float, "getWidth": int, "getHeight": int, "getMinRange": float, "getMaxRange": float,
    },
    "Display": {
        "getWidth": int, "getHeight": int, "setColor": None, "setAlpha": None, "setOpacity": None, "setFont": None,
        "attachCamera": None, "detachCamera": None, "drawPixel": None, "drawLine": None, "drawRectangle": None,
        "drawOval": None, "drawPolygon": None, "drawText": None, "fillRectangle": None, "fillOval": None,
        "fillPolygon": None,
        "imageNew": int, "imageLoad": int, "imageCopy": int,  # an image reference: an opaque int
        "imagePaste": None, "imageSave": None, "imageDelete": None,
    },
    "LED": {"set": None, "get": int},
    "Pen": {"write": None, "setInkColor": None},
    "Speaker": {
        "playSound": None, "stop": None, "isSoundPlaying": bool, "speak": None, "isSpeaking": bool,
        "setEngine": bool, "setLanguage": bool, "getEngine": str, "getLanguage": str,
    },
    "LightSensor": {"getValue": float, "getLookupTable": LF},
    "Altimeter": {"getValue": float},
    "Radar": {
        "getTargets": list[RadarTarget], "getNumberOfTargets": int, "getMinRange": float, "getMaxRange": float,
        "getHorizontalFov": float, "getVerticalFov": float,
    },
    "VacuumGripper": {
        "enablePresence": None, "disablePresence": None, "getPresence": bool, "getPresenceSamplingPeriod": int,
        "isOn": bool, "turnOn": None, "turnOff": None,
    },
    "Mouse": {
        "enable": None, "disable": None, "getSamplingPeriod": int, "getState": MouseState, "enable3dPosition": None,
        "disable3dPosition": None, "is3dPositionEnabled": bool,
    },
    "Joystick": {
        "enable": None, "disable": None, "getSamplingPeriod": int, "isConnected": bool, "getNumberOfAxes": int,
        "getAxisValue": int, "getNumberOfPovs": int, "getPovValue": int, "getPressedButton": int,
        "setConstantForce": None, "setConstantForceDuration": None, "setAutoCenteringGain": None,
        "setResistanceGain": None, "setForceAxis": None,
    },
    "Motion": {
        "isValid": bool, "play": None, "stop": None, "setLoop": None, "setReverse": None, "isOver": bool,
        "getDuration": int, "getTime": int, "setTime": None,
    },
}

# ------------------------------------------------------------------ what each class is called on

_SINGLE = {
    "Connector": "con", "DistanceSensor": "ds", "Lidar": "lidar", "Camera": "cam", "TouchSensor": "touch",
    "Emitter": "emitter", "Receiver": "rx", "GPS": "gps", "Gyro": "gyro", "Accelerometer": "acc",
    "InertialUnit": "imu", "Compass": "compass", "RangeFinder": "range", "Display": "display", "LED": "led",
    "Pen": "pen", "Speaker": "speaker", "LightSensor": "light", "Altimeter": "alt", "Radar": "radar",
    "VacuumGripper": "cup", "Brake": "brake",
}
TARGETS: dict[str, Callable[[RichWorld], list[Any]]] = {
    **{cls: (lambda w, n=name: [w.dev[n]]) for cls, name in _SINGLE.items()},
    "Robot": lambda w: [w.sup],
    "Supervisor": lambda w: [w.sup],
    "Node": lambda w: [w.nodes["BOX"]],
    "ContactPoint": lambda w: w.nodes["BOX"].getContactPoints(),
    "Field": lambda w: list(w.fields.values()),
    "Device": lambda w: list(w.dev.values()),
    "Sensor": lambda w: [d for d in w.dev.values() if isinstance(d, Sensor)],
    "Motor": lambda w: [w.dev["rm"], w.dev["lm"]],
    "PositionSensor": lambda w: [w.dev["ps"], w.dev["lps"]],
    "Keyboard": lambda w: [w.sup.getKeyboard()],
    "CameraRecognitionObject": lambda w: w.dev["cam"].getRecognitionObjects(),
    "Mouse": lambda w: [w.sup.getMouse()],
    "Joystick": lambda w: [w.sup.getJoystick()],
    "Motion": lambda w: [Motion(str(w.folder / "turn.motion"))],
}

# field methods named after a field type are called on the field of that type
_FIELD_TYPE = re.compile(r"(?:get|set|insert)((?:SF|MF)\w+)$")
_MF_VALUES = {"Bool": True, "Int32": 1, "Float": 0.5, "Vec2f": [0.0, 1.0], "Vec3f": [0.0, 0.0, 1.0],
              "Rotation": [0.0, 0.0, 1.0, 0.5], "Color": [0.0, 1.0, 0.0], "String": "x"}
_SF_VALUES = {**_MF_VALUES, "Int32": 16, "Float": 2.0}


def _field_call(w: RichWorld, method: str) -> tuple[list[Any], tuple[Any, ...]]:
    """The fields a Field method is called on, and its arguments."""
    typed = _FIELD_TYPE.match(method)
    if typed is not None:
        kind = typed.group(1)
        value = (_SF_VALUES if kind.startswith("SF") else _MF_VALUES).get(kind[2:])
        index = () if kind.startswith("SF") else (0,)
        args = index if method.startswith("get") else (*index, value)
        return [w.fields[kind]], args
    special: dict[str, tuple[str, tuple[Any, ...]]] = {
        "enableSFTracking": ("SFVec3f", (8,)), "disableSFTracking": ("SFVec3f", ()),
        "removeMF": ("MFString", (0,)), "removeSF": ("SFNode", ()),
        "importMFNodeFromString": ("MFNode", (-1, "Solid { }")),
        "importSFNodeFromString": ("SFNode", ("Sphere { radius 0.1 }",)),
    }
    if method in special:
        kind, args = special[method]
        return [w.fields[kind]], args
    return list(w.fields.values()), ()


def _folder(w: RichWorld, name: str) -> str:
    return str(w.folder / name)


def _begin_end(robot: Robot, part: str) -> Any:
    begin = robot.stepBegin(8)
    end = robot.stepEnd()
    return begin if part == "begin" else end


def _image_ref(display: Display) -> Any:
    return display.imageCopy(0, 0, 2, 2)


def _saved_then_loaded(display: Display, path: str) -> Any:
    display.imageSave(None, path)
    return display.imageLoad(path)


class Each(list[Any]):
    """Several results of one call (each is checked)."""


#: calls that need arguments or a preparation, as "Class.method": (world, object) -> result
CALLS: dict[str, Callable[[RichWorld, Any], Any]] = {
    "Robot.getDevice": lambda w, o: Each(o.getDevice(name) for name in w.dev),  # the speaker's too
    "Robot.getDeviceByIndex": lambda w, o: Each(o.getDeviceByIndex(i) for i in range(o.getNumberOfDevices())),
    "Robot.setCustomData": lambda w, o: o.setCustomData("other"),
    "Robot.wwiSendText": lambda w, o: o.wwiSendText("hello"),
    "Robot.step": lambda w, o: o.step(8),
    "Robot.stepBegin": lambda w, o: _begin_end(o, "begin"),
    "Robot.stepEnd": lambda w, o: _begin_end(o, "end"),
    "Robot.waitForUserInputEvent": lambda w, o: o.waitForUserInputEvent(o.EVENT_KEYBOARD, 8),
    "Robot.batterySensorEnable": lambda w, o: o.batterySensorEnable(16),
    "Robot.setMode": lambda w, o: o.setMode(o.MODE_SIMULATION, None),
    "Supervisor.getFromDef": lambda w, o: o.getFromDef("BOX"),
    "Supervisor.getFromId": lambda w, o: o.getFromId(w.nodes["BOX"].getId()),
    "Supervisor.getFromDevice": lambda w, o: o.getFromDevice(w.dev["cam"]._tag),
    "Supervisor.setLabel": lambda w, o: o.setLabel(0, "label", 0.1, 0.1, 0.1, 0xFF0000),
    "Supervisor.simulationQuit": lambda w, o: o.simulationQuit(0),
    "Supervisor.simulationSetMode": lambda w, o: o.simulationSetMode(o.SIMULATION_MODE_FAST),
    "Supervisor.worldLoad": lambda w, o: o.worldLoad(_folder(w, "rich.wbt")),
    "Supervisor.worldSave": lambda w, o: o.worldSave(_folder(w, "saved.wbt")),
    "Supervisor.exportImage": lambda w, o: o.exportImage(_folder(w, "view.png"), 90),
    "Supervisor.movieStartRecording": lambda w, o: o.movieStartRecording(
        _folder(w, "movie.mp4"), 64, 48, 0, 90, 1, False),
    "Supervisor.animationStartRecording": lambda w, o: o.animationStartRecording(_folder(w, "animation.html")),
    "Node.getFromProtoDef": lambda w, o: w.nodes["FLAGS"].getFromProtoDef("INNER"),
    "Node.getField": lambda w, o: o.getField("translation"),
    "Node.getFieldByIndex": lambda w, o: o.getFieldByIndex(0),
    "Node.getProtoField": lambda w, o: w.nodes["FLAGS"].getProtoField("translation"),
    "Node.getProtoFieldByIndex": lambda w, o: w.nodes["FLAGS"].getProtoFieldByIndex(0),
    "Node.isProto": lambda w, o: w.nodes["FLAGS"].isProto(),
    "Node.enablePoseTracking": lambda w, o: o.enablePoseTracking(8),
    "Node.enableContactPointsTracking": lambda w, o: o.enableContactPointsTracking(8),
    "Node.setVelocity": lambda w, o: o.setVelocity([0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
    "Node.saveState": lambda w, o: o.saveState("state"),
    "Node.loadState": lambda w, o: (o.saveState("state"), o.loadState("state"))[1],
    "Node.setJointPosition": lambda w, o: w.sup.getFromDevice(w.dev["rm"]._tag).getParentNode().setJointPosition(0.1),
    "Node.restartController": lambda w, o: w.nodes["TALKER"].restartController(),
    "Node.setVisibility": lambda w, o: o.setVisibility(w.sup.getFromDevice(w.dev["cam"]._tag), False),
    "Node.addForce": lambda w, o: o.addForce([0.0, 0.0, 1.0], False),
    "Node.addForceWithOffset": lambda w, o: o.addForceWithOffset([0.0, 0.0, 1.0], [0.1, 0.0, 0.0], False),
    "Node.addTorque": lambda w, o: o.addTorque([0.0, 0.0, 1.0], False),
    "Sensor.enable": lambda w, o: o.enable(16),
    "Motor.setPosition": lambda w, o: o.setPosition(0.1),
    "Motor.setVelocity": lambda w, o: o.setVelocity(1.0),
    "Motor.setAcceleration": lambda w, o: o.setAcceleration(-1),
    "Motor.setAvailableForce": lambda w, o: o.setAvailableForce(1.0),
    "Motor.setAvailableTorque": lambda w, o: o.setAvailableTorque(1.0),
    "Motor.setControlPID": lambda w, o: o.setControlPID(10.0, 0.0, 0.0),
    "Motor.setForce": lambda w, o: o.setForce(0.5),
    "Motor.setTorque": lambda w, o: o.setTorque(0.5),
    "Motor.enableForceFeedback": lambda w, o: o.enableForceFeedback(16),
    "Motor.enableTorqueFeedback": lambda w, o: o.enableTorqueFeedback(16),
    "Brake.setDampingConstant": lambda w, o: o.setDampingConstant(0.1),
    "Keyboard.enable": lambda w, o: o.enable(16),
    "Connector.enablePresence": lambda w, o: o.enablePresence(16),
    "Lidar.getLayerRangeImage": lambda w, o: o.getLayerRangeImage(1),
    "Lidar.getLayerPointCloud": lambda w, o: o.getLayerPointCloud(1),
    "Lidar.setFrequency": lambda w, o: o.setFrequency(1.0),
    "Camera.imageGetRed": lambda w, o: o.imageGetRed(o.getImage(), o.getWidth(), 1, 1),
    "Camera.imageGetGreen": lambda w, o: o.imageGetGreen(o.getImage(), o.getWidth(), 1, 1),
    "Camera.imageGetBlue": lambda w, o: o.imageGetBlue(o.getImage(), o.getWidth(), 1, 1),
    "Camera.imageGetGray": lambda w, o: o.imageGetGray(o.getImage(), o.getWidth(), 1, 1),
    "Camera.saveImage": lambda w, o: o.saveImage(_folder(w, "camera.png"), 90),
    "Camera.setFov": lambda w, o: o.setFov(0.5),
    "Camera.setExposure": lambda w, o: o.setExposure(2.0),
    "Camera.setFocalDistance": lambda w, o: o.setFocalDistance(1.0),
    "Camera.recognitionEnable": lambda w, o: o.recognitionEnable(16),
    "Camera.saveRecognitionSegmentationImage": lambda w, o: o.saveRecognitionSegmentationImage(
        _folder(w, "segmentation.png"), 90),
    "Emitter.send": lambda w, o: o.send([1.0, 2.0]),
    "Emitter.setChannel": lambda w, o: o.setChannel(2),
    "Emitter.setRange": lambda w, o: o.setRange(5.0),
    "Receiver.setChannel": lambda w, o: o.setChannel(2),
    "GPS.convertToDegreesMinutesSeconds": lambda w, o: o.convertToDegreesMinutesSeconds(46.5),
    "RangeFinder.rangeImageGetDepth": lambda w, o: o.rangeImageGetDepth(o.getRangeImage(), o.getWidth(), 1, 1),
    "RangeFinder.saveImage": lambda w, o: o.saveImage(_folder(w, "range.png"), 90),
    "Display.setColor": lambda w, o: o.setColor(0xFF0000),
    "Display.setAlpha": lambda w, o: o.setAlpha(0.5),
    "Display.setOpacity": lambda w, o: o.setOpacity(0.5),
    "Display.setFont": lambda w, o: o.setFont("Arial", 8, True),
    "Display.attachCamera": lambda w, o: o.attachCamera(w.dev["cam"]),
    "Display.drawPixel": lambda w, o: o.drawPixel(1, 1),
    "Display.drawLine": lambda w, o: o.drawLine(0, 0, 3, 3),
    "Display.drawRectangle": lambda w, o: o.drawRectangle(0, 0, 3, 3),
    "Display.drawOval": lambda w, o: o.drawOval(3, 3, 2, 1),
    "Display.drawPolygon": lambda w, o: o.drawPolygon([0, 3, 1], [0, 0, 3]),
    "Display.drawText": lambda w, o: o.drawText("a", 0, 0),
    "Display.fillRectangle": lambda w, o: o.fillRectangle(0, 0, 3, 3),
    "Display.fillOval": lambda w, o: o.fillOval(3, 3, 2, 1),
    "Display.fillPolygon": lambda w, o: o.fillPolygon([0, 3, 1], [0, 0, 3]),
    "Display.imageNew": lambda w, o: o.imageNew(bytes(2 * 2 * 4), Display.BGRA, 2, 2),
    "Display.imageLoad": lambda w, o: _saved_then_loaded(o, _folder(w, "display.png")),
    "Display.imageCopy": lambda w, o: o.imageCopy(0, 0, 2, 2),
    "Display.imagePaste": lambda w, o: o.imagePaste(_image_ref(o), 1, 1, False),
    "Display.imageSave": lambda w, o: o.imageSave(_image_ref(o), _folder(w, "copy.png")),
    "Display.imageDelete": lambda w, o: o.imageDelete(_image_ref(o)),
    "LED.set": lambda w, o: o.set(1),
    "Pen.write": lambda w, o: o.write(True),
    "Pen.setInkColor": lambda w, o: o.setInkColor(0xFF0000, 0.5),
    "Speaker.playSound": lambda w, o: o.playSound(o, o, "sound.wav", 1.0, 1.0, 0.0, False),
    "Speaker.isSoundPlaying": lambda w, o: o.isSoundPlaying("sound.wav"),
    "Speaker.speak": lambda w, o: o.speak("hello", 1.0),
    "Speaker.setEngine": lambda w, o: o.setEngine("pico"),
    "Speaker.setLanguage": lambda w, o: o.setLanguage("en-US"),
    "VacuumGripper.enablePresence": lambda w, o: o.enablePresence(16),
    "Mouse.enable": lambda w, o: o.enable(16),
    "Joystick.enable": lambda w, o: o.enable(16),
    "Joystick.getAxisValue": lambda w, o: o.getAxisValue(0),
    "Joystick.getPovValue": lambda w, o: o.getPovValue(0),
    "Joystick.setConstantForce": lambda w, o: o.setConstantForce(1),
    "Joystick.setConstantForceDuration": lambda w, o: o.setConstantForceDuration(1.0),
    "Joystick.setAutoCenteringGain": lambda w, o: o.setAutoCenteringGain(1.0),
    "Joystick.setResistanceGain": lambda w, o: o.setResistanceGain(1.0),
    "Joystick.setForceAxis": lambda w, o: o.setForceAxis(0),
    "Motion.setLoop": lambda w, o: o.setLoop(True),
    "Motion.setReverse": lambda w, o: o.setReverse(False),
    "Motion.setTime": lambda w, o: o.setTime(40),
}

#: calls that change the world (or the current robot) for others besides commands: each on a world of its own
FRESH = {"Robot.step", "Robot.stepBegin", "Robot.stepEnd", "Supervisor.worldSave",
         "Supervisor.animationStartRecording", "Speaker.setEngine", "Speaker.setLanguage"} | {
    f"Motion.{m}" for m in RETURNS["Motion"]}

#: (class, method) -> why the item is expected to fail
XFAIL: dict[str, str] = {}


def _items() -> Iterator[Any]:
    for cls, methods in RETURNS.items():
        for method in methods:
            key = f"{cls}.{method}"
            marks = [pytest.mark.xfail(strict=True, reason=XFAIL[key])] if key in XFAIL else []
            yield pytest.param(cls, method, id=key, marks=marks)


ITEMS = list(_items())


@pytest.fixture(scope="module")
def rich(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RichWorld]:
    world = RichWorld.build(tmp_path_factory.mktemp("rich"))
    yield world
    world.close()


def _call(world: RichWorld, cls: str, method: str) -> list[tuple[Any, Any]]:
    """(object, result) for every object the method is called on."""
    key = f"{cls}.{method}"
    if cls == "Field":
        fields, args = _field_call(world, method)
        return [(f, getattr(f, method)(*args)) for f in fields]
    targets = TARGETS[cls](world)
    assert targets, f"nothing to call {key} on"
    call = CALLS.get(key, lambda w, o: getattr(o, method)())
    out = []
    for obj in targets:
        result = call(world, obj)
        out += [(obj, r) for r in result] if isinstance(result, Each) else [(obj, result)]
    return out


@pytest.mark.filterwarnings("ignore:Solid 'box' has Physics but no boundingObject")  # Field.removeSF
@pytest.mark.parametrize(("cls", "method"), ITEMS)
def test_return_type(cls: str, method: str, request: pytest.FixtureRequest, tmp_path: Path) -> None:
    spec = RETURNS[cls][method]
    key = f"{cls}.{method}"
    own = spec is None or key in FRESH
    world = RichWorld.build(tmp_path / "world") if own else request.getfixturevalue("rich")
    try:
        for obj, result in _call(world, cls, method):
            assert conforms(result, spec), (
                f"{key} on {type(obj).__name__} returned {describe(result)}; Webots returns {spec_text(spec)}")
    finally:
        if own:
            world.close()


def test_every_class_has_targets_and_every_call_names_a_table_entry() -> None:
    assert set(TARGETS) | {"Field"} == set(RETURNS)
    for key in CALLS:
        cls, method = key.split(".")
        assert method in RETURNS[cls], key
    assert len(ITEMS) == sum(len(m) for m in RETURNS.values())


# ------------------------------------------------------------------ the same types through a controller process

PROCESS_CALLS = {
    "getTime": ("robot.getTime()", "float"),
    "gps": ("robot.getDevice('gps').getValues()", "list"),
    "gps[0]": ("robot.getDevice('gps').getValues()[0]", "float"),
    "getNumberOfDevices": ("robot.getNumberOfDevices()", "int"),
    "getSFBool": ("robot.getSelf().getField('supervisor').getSFBool()", "int"),
    "getPresence": ("robot.getDevice('con').getPresence()", "int"),
    "getImage": ("robot.getDevice('cam').getImage()", "bytes"),
    "getName": ("robot.getName()", "str"),
    "getFloats": ("robot.getDevice('rx').getFloats()", "tuple"),
    "getPosition": ("robot.getSelf().getPosition()", "list"),
    "getPosition[0]": ("robot.getSelf().getPosition()[0]", "float"),
    "getRangeImage[0]": ("robot.getDevice('lidar').getRangeImage()[0]", "float"),
    "imageCopy": ("robot.getDevice('display').imageCopy(0, 0, 1, 1)", "int"),
}

PROCESS_WORLD = """#VRML_SIM R2023b utf8
WorldInfo { basicTimeStep 8 }
Robot { name "talker" translation 0 2 0 children [ Emitter { name "tx" } ] controller "talker" }
Robot {
  name "probe"
  children [ GPS { name "gps" } Connector { name "con" } Camera { name "cam" width 4 height 3 }
             Receiver { name "rx" } Lidar { name "lidar" horizontalResolution 4 fieldOfView 1 }
             Display { name "display" width 2 height 2 } ]
  controller "probe"
  supervisor TRUE
}
"""


def test_types_cross_a_controller_process(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "worlds").mkdir()
    world = tmp_path / "worlds" / "w.wbt"
    world.write_text(PROCESS_WORLD)
    talker = "from controller import Robot\nrobot = Robot()\nrobot.getDevice('tx').send([1.5, 2.5])\nrobot.step(8)\n"
    lines = "\n".join(f"print({name!r}, type({expr}).__name__)" for name, (expr, _) in PROCESS_CALLS.items())
    probe = textwrap.dedent("""
        from controller import Supervisor
        robot = Supervisor()
        for name in ("gps", "cam", "rx", "lidar", "con"):
            device = robot.getDevice(name)
            (device.enablePresence if name == "con" else device.enable)(8)
        robot.step(8)
        robot.step(8)
    """) + lines + "\n"
    for name, script in (("talker", talker), ("probe", probe)):
        (tmp_path / "controllers" / name).mkdir(parents=True)
        (tmp_path / "controllers" / name / f"{name}.py").write_text(script)
    assert run_world(world, None, 0.05, isolation="process") == 0
    seen = dict(line.split(" ", 1) for line in capsys.readouterr().out.splitlines() if line.count(" ") == 1)
    assert {k.strip("'"): v for k, v in seen.items()} == {name: t for name, (_, t) in PROCESS_CALLS.items()}
