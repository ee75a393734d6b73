"""Webots R2023b's Python controller API, name for name (issue 23): every class, every name, its kind, its parameters.

``API`` below is our own encoding of Webots' controller surface (what ``from controller import X`` offers a
controller): per class the constants (with their values), plain attributes, read-only / settable / write-only
properties, methods and static methods with Webots' parameter names and defaults. Every name is one test item, so a
missing or changed name fails by name; ``test_api_figure`` prints the figure ``N/846 names match``.

How a kind is recognised on our classes:

- constant: a class attribute that is not a function or descriptor, equal to Webots' value (AnsiCodes: a str);
- plain attribute: a class attribute (``Robot.created``) or an annotated instance attribute, never a property;
- read-only / settable / write-only property: a ``property`` with getter only / getter and setter / setter only;
- method: a plain function; static: a ``staticmethod``. Webots' parameters must come first, positional-or-keyword,
  with the same names and defaults; anything we add must be keyword-only with a default (a Webots call cannot
  tell the difference).

``importable=False``: not in ``controller/__init__.py`` (Device, Sensor, and Pen, which only ``controller.pen``
offers); their names are still counted and looked up on :mod:`dualtwin.webots.controller`.
R2024a-only names (``Proto``, ``Node.getBaseNodeField*``, ``Field.getActualField``...) are not part of the 846.
Run ``python tests/webots/test_api_surface.py`` for the list of mismatches.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import types
from dataclasses import dataclass
from typing import Any

import pytest

TOTAL = 846  # names in Webots R2023b's Python API as counted by issue 23 (exports + class names + deprecated getters)


@dataclass(frozen=True)
class Cls:
    """One Webots class: space-separated names per kind; methods as ``name(p1,p2=default)``."""

    base: str = ""
    importable: bool = True
    consts: str = ""
    attr: str = ""
    ro: str = ""
    rw: str = ""
    wo: str = ""
    methods: str = ""
    static: str = ""


# Robot's 24 deprecated device getters: each ``(name)``, getDevice plus a DEPRECATION line on stderr
DEPRECATED_GETTERS = [
    "Accelerometer", "Altimeter", "Brake", "Camera", "Compass", "Connector", "Display", "DistanceSensor", "Emitter",
    "GPS", "Gyro", "InertialUnit", "LED", "Lidar", "LightSensor", "Motor", "Pen", "PositionSensor", "Radar",
    "RangeFinder", "Receiver", "Skin", "Speaker", "TouchSensor",
]

API: dict[str, Cls] = {
    "Robot": Cls(
        consts=(
            "EVENT_QUIT=-1 EVENT_NO_EVENT=0 EVENT_MOUSE_CLICK=1 EVENT_MOUSE_MOVE=2 EVENT_KEYBOARD=4 "
            "EVENT_JOYSTICK_BUTTON=8 EVENT_JOYSTICK_AXIS=16 EVENT_JOYSTICK_POV=32 MODE_SIMULATION=0 "
            "MODE_CROSS_COMPILATION=1 MODE_REMOTE_CONTROL=2"
        ),
        attr="created devices keyboard mouse joystick",
        ro=(
            "basic_time_step name model project_path world_path supervisor synchronization time number_of_devices "
            "mode"
        ),
        rw="custom_data battery_sensor_sampling_period",
        methods=(
            "__init__() getDevice(name) getDeviceByIndex(index) getNumberOfDevices() getKeyboard() getMouse() "
            "getJoystick() getBasicTimeStep() getTime() getName() getModel() getCustomData() setCustomData(data) "
            "getProjectPath() getWorldPath() getSupervisor() getSynchronization() getUrdf(prefix='') "
            "wwiSendText(text) wwiReceiveText() step(time_step=None) stepBegin(time_step=None) stepEnd() "
            "waitForUserInputEvent(event_type,timeout) batterySensorEnable(sampling_period) "
            "batterySensorDisable() batterySensorGetSamplingPeriod() batterySensorGetValue() getMode() "
            "setMode(mode,arg)"
        ),
    ),
    "Supervisor": Cls(
        base="Robot",
        consts="SIMULATION_MODE_PAUSE=0 SIMULATION_MODE_REAL_TIME=1 SIMULATION_MODE_FAST=2",
        rw="simulation_mode",
        methods=(
            "__init__() getRoot() getSelf() getFromDef(d) getFromId(id) getFromDevice(tag) getSelected() "
            "setLabel(id,label,x,y,size,color,transparency=0,font='Arial') simulationQuit(status) "
            "simulationSetMode(mode) simulationGetMode() simulationReset() simulationResetPhysics() "
            "worldLoad(filename) worldSave(filename=None) worldReload() exportImage(filename,quality) "
            "movieStartRecording(filename,width,height,codec,quality,acceleration,caption) movieStopRecording() "
            "movieIsReady() movieFailed() animationStartRecording(filename) animationStopRecording() "
            "virtualRealityHeadsetIsUsed() virtualRealityHeadsetGetPosition() "
            "virtualRealityHeadsetGetOrientation()"
        ),
    ),
    "Node": Cls(
        consts=(
            "NO_NODE=0 APPEARANCE=1 BACKGROUND=2 BILLBOARD=3 BOX=4 CAD_SHAPE=5 CAPSULE=6 COLOR=7 CONE=8 "
            "COORDINATE=9 CYLINDER=10 DIRECTIONAL_LIGHT=11 ELEVATION_GRID=12 FOG=13 GROUP=14 IMAGE_TEXTURE=15 "
            "INDEXED_FACE_SET=16 INDEXED_LINE_SET=17 MATERIAL=18 MESH=19 MUSCLE=20 NORMAL=21 PBR_APPEARANCE=22 "
            "PLANE=23 POINT_LIGHT=24 POINT_SET=25 SHAPE=27 SPHERE=28 SPOT_LIGHT=29 TEXTURE_COORDINATE=30 "
            "TEXTURE_TRANSFORM=31 TRANSFORM=32 VIEWPOINT=33 ROBOT=34 ACCELEROMETER=35 ALTIMETER=36 BRAKE=37 "
            "CAMERA=38 COMPASS=39 CONNECTOR=40 DISPLAY=41 DISTANCE_SENSOR=42 EMITTER=43 GPS=44 GYRO=45 "
            "INERTIAL_UNIT=46 LED=47 LIDAR=48 LIGHT_SENSOR=49 LINEAR_MOTOR=50 PEN=51 POSITION_SENSOR=52 RADAR=54 "
            "RANGE_FINDER=55 RECEIVER=56 ROTATIONAL_MOTOR=57 SKIN=58 SPEAKER=59 TOUCH_SENSOR=60 VACUUM_GRIPPER=61 "
            "BALL_JOINT=62 BALL_JOINT_PARAMETERS=63 CHARGER=64 CONTACT_PROPERTIES=65 DAMPING=66 FLUID=67 FOCUS=68 "
            "HINGE_JOINT=69 HINGE_JOINT_PARAMETERS=70 HINGE_2_JOINT=71 IMMERSION_PROPERTIES=72 "
            "JOINT_PARAMETERS=73 LENS=74 LENS_FLARE=75 PHYSICS=76 RECOGNITION=77 SLIDER_JOINT=78 SLOT=79 SOLID=80 "
            "SOLID_REFERENCE=81 TRACK=82 TRACK_WHEEL=83 WORLD_INFO=84 ZOOM=85 MICROPHONE=86 RADIO=87"
        ),
        ro="DEF id type type_name base_type_name number_of_fields",
        methods=(
            "getDef() getId() getParentNode() isProto() getFromProtoDef(DEF) getType() getTypeName() "
            "getBaseTypeName() remove() exportString() getField(name) getFieldByIndex(index) getNumberOfFields() "
            "getProtoField(name) getProtoFieldByIndex(index) getPosition() getOrientation() "
            "getPose(fromNode=None) enablePoseTracking(samplingPeriod,fromNode=None) "
            "disablePoseTracking(fromNode=None) getCenterOfMass() getContactPoints(includeDescendants=False) "
            "enableContactPointsTracking(samplingPeriod,includeDescendants=False) "
            "disableContactPointsTracking(includeDescendants=False) getStaticBalance() getVelocity() "
            "setVelocity(velocity) saveState(stateName) loadState(stateName) resetPhysics() "
            "setJointPosition(position,index=1) restartController() moveViewpoint() "
            "setVisibility(fromNode,visible) addForce(force,relative) addForceWithOffset(force,offset,relative) "
            "addTorque(torque,relative)"
        ),
    ),
    "ContactPoint": Cls(
        attr="point node_id",
        methods="getPoint() getNodeId()",
    ),
    "Field": Cls(
        consts=(
            "SF_BOOL=1 SF_INT32=2 SF_FLOAT=3 SF_VEC2F=4 SF_VEC3F=5 SF_ROTATION=6 SF_COLOR=7 SF_STRING=8 SF_NODE=9 "
            "MF_BOOL=17 MF_INT32=18 MF_FLOAT=19 MF_VEC2F=20 MF_VEC3F=21 MF_ROTATION=22 MF_COLOR=23 MF_STRING=24 "
            "MF_NODE=25"
        ),
        attr="type",
        ro="name type_name count",
        rw="value",
        methods=(
            "getName() getType() getTypeName() getCount() enableSFTracking(samplingPeriod) disableSFTracking() "
            "getSFBool() getSFInt32() getSFFloat() getSFVec2f() getSFVec3f() getSFRotation() getSFColor() "
            "getSFString() getSFNode() getMFBool(index) getMFInt32(index) getMFFloat(index) getMFVec2f(index) "
            "getMFVec3f(index) getMFRotation(index) getMFColor(index) getMFString(index) getMFNode(index) "
            "setSFBool(value) setSFInt32(value) setSFFloat(value) setSFVec2f(value) setSFVec3f(value) "
            "setSFRotation(value) setSFColor(value) setSFString(value) setMFBool(index,value) "
            "setMFInt32(index,value) setMFFloat(index,value) setMFVec2f(index,value) setMFVec3f(index,value) "
            "setMFRotation(index,value) setMFColor(index,value) setMFString(index,value) "
            "insertMFBool(index,value) insertMFInt32(index,value) insertMFFloat(index,value) "
            "insertMFVec2f(index,value) insertMFVec3f(index,value) insertMFRotation(index,value) "
            "insertMFColor(index,value) insertMFString(index,value) removeMF(index) removeSF() "
            "importMFNodeFromString(position,nodeString) importSFNodeFromString(nodeString)"
        ),
    ),
    "Device": Cls(
        importable=False,
        ro="name model node_type",
        methods="getName() getModel() getNodeType()",
    ),
    "Sensor": Cls(
        base="Device",
        importable=False,
        rw="sampling_period",
        methods="__init__(name,sampling_period=None) enable(p) disable() getSamplingPeriod()",
    ),
    "Motor": Cls(
        base="Device",
        consts="ROTATIONAL=0 LINEAR=1",
        ro=(
            "brake position_sensor max_position min_position max_velocity max_force max_torque multiplier "
            "force_feedback torque_feedback type"
        ),
        rw=(
            "force_feedback_sampling_period torque_feedback_sampling_period target_position target_velocity "
            "target_acceleration available_force available_torque"
        ),
        wo="force torque",
        methods=(
            "__init__(name) setPosition(position) setVelocity(velocity) setAcceleration(acceleration) "
            "setAvailableForce(force) setAvailableTorque(torque) setControlPID(p,i,d) setForce(force) "
            "setTorque(torque) getTargetPosition() getMinPosition() getMaxPosition() getVelocity() "
            "getMaxVelocity() getAcceleration() getAvailableForce() getMaxForce() getAvailableTorque() "
            "getMaxTorque() getMultiplier() enableForceFeedback(sampling_period) disableForceFeedback() "
            "getForceFeedbackSamplingPeriod() getForceFeedback() enableTorqueFeedback(sampling_period) "
            "disableTorqueFeedback() getTorqueFeedbackSamplingPeriod() getTorqueFeedback() getType() getBrake() "
            "getPositionSensor()"
        ),
    ),
    "PositionSensor": Cls(
        base="Sensor",
        consts="ROTATIONAL=0 LINEAR=1",
        ro="brake motor value type",
        methods="getValue() getType() getBrake() getMotor()",
    ),
    "Brake": Cls(
        base="Device",
        consts="ROTATIONAL=0 LINEAR=1",
        ro="motor position_sensor type",
        wo="dampingConstant",
        methods="__init__(name) setDampingConstant(c) getType() getMotor() getPositionSensor()",
    ),
    "Keyboard": Cls(
        consts=(
            "END=312 HOME=313 LEFT=314 UP=315 RIGHT=316 DOWN=317 PAGEUP=366 PAGEDOWN=367 NUMPAD_HOME=375 "
            "NUMPAD_LEFT=376 NUMPAD_UP=377 NUMPAD_RIGHT=378 NUMPAD_DOWN=379 NUMPAD_END=382 KEY=65535 SHIFT=65536 "
            "CONTROL=131072 ALT=262144"
        ),
        rw="sampling_period",
        methods=(
            "__init__(sampling_period=None) enable(p) disable() getSamplingPeriod() getKey() getKeyCode() "
            "get_key()"
        ),
    ),
    "Connector": Cls(
        base="Device",
        ro="locked presence presence_sampling_period",
        methods=(
            "__init__(name) enablePresence(sampling_period) disablePresence() getPresence() "
            "getPresenceSamplingPeriod() isLocked() lock() unlock()"
        ),
    ),
    "DistanceSensor": Cls(
        base="Sensor",
        consts="GENERIC=0 INFRA_RED=1 SONAR=2 LASER=3",
        ro="value max_value min_value aperture lookup_table type",
        methods="getValue() getMaxValue() getMinValue() getAperture() getLookupTable() getType()",
    ),
    "Lidar": Cls(
        base="Sensor",
        ro=(
            "range_image fov vertical_fov max_frequency min_frequency max_range min_range horizontal_resolution "
            "number_of_layers number_of_points"
        ),
        rw="frequency",
        methods=(
            "getRangeImage() getRangeImageArray() getLayerRangeImage(layer) enablePointCloud() "
            "disablePointCloud() isPointCloudEnabled() getPointCloud() getLayerPointCloud(layer) "
            "getNumberOfPoints() getFrequency() setFrequency(frequency) getMinFrequency() getMaxFrequency() "
            "getFov() getVerticalFov() getHorizontalResolution() getNumberOfLayers() getMinRange() getMaxRange()"
        ),
    ),
    "LidarPoint": Cls(
        attr="x y z layer time",
        methods="__init__(data,offset)",
    ),
    "Camera": Cls(
        base="Sensor",
        ro=(
            "image segmentation_image focal_length max_focal_distance min_focal_distance height width min_fov "
            "max_fov near"
        ),
        rw="exposure focal_distance fov",
        methods=(
            "getImage() getImageArray() saveImage(filename,quality) getWidth() getHeight() getFov() setFov(f) "
            "getMinFov() getMaxFov() getExposure() setExposure(exposure) getFocalLength() getFocalDistance() "
            "setFocalDistance(d) getMinFocalDistance() getMaxFocalDistance() getNear() hasRecognition() "
            "recognitionEnable(sampling_period) recognitionDisable() getRecognitionSamplingPeriod() "
            "getRecognitionNumberOfObjects() getRecognitionObjects() hasRecognitionSegmentation() "
            "enableRecognitionSegmentation() disableRecognitionSegmentation() isRecognitionSegmentationEnabled() "
            "getRecognitionSegmentationImage() getRecognitionSegmentationImageArray() "
            "saveRecognitionSegmentationImage(filename,quality)"
        ),
        static=(
            "imageGetRed(image,width,x,y) imageGetGreen(image,width,x,y) imageGetBlue(image,width,x,y) "
            "imageGetGray(image,width,x,y)"
        ),
    ),
    "CameraRecognitionObject": Cls(
        attr="id position orientation size position_on_image size_on_image number_of_colors colors",
        ro="model",
        methods=(
            "getId() getPosition() getOrientation() getSize() getPositionOnImage() getSizeOnImage() "
            "getNumberOfColors() getColors() getModel()"
        ),
    ),
    "TouchSensor": Cls(
        base="Sensor",
        consts="BUMPER=0 FORCE=1 FORCE3D=2",
        ro="value values lookup_table type",
        methods="getValue() getValues() getLookupTable() getType()",
    ),
    "Emitter": Cls(
        base="Device",
        consts="CHANNEL_BROADCAST=-1",
        ro="buffer_size",
        rw="channel range",
        methods=(
            "__init__(name) send(message,length=None) getChannel() setChannel(channel) getRange() setRange(range) "
            "getBufferSize()"
        ),
    ),
    "Receiver": Cls(
        base="Sensor",
        ro="queue_length data data_size string signal_strength emitter_direction",
        rw="channel",
        methods=(
            "getQueueLength() nextPacket() getBytes() getString() getData() getDataSize() getFloats() getInts() "
            "getBools() getSignalStrength() getEmitterDirection() getChannel() setChannel(channel)"
        ),
    ),
    "GPS": Cls(
        base="Sensor",
        consts="LOCAL=0 WGS84=1",
        ro="value speed speed_vector coordinate_system",
        methods="getValues() getSpeed() getSpeedVector() getCoordinateSystem()",
        static="convertToDegreesMinutesSeconds(decimalDegrees)",
    ),
    "Gyro": Cls(
        base="Sensor",
        ro="value lookup_table",
        methods="getValues() getLookupTable()",
    ),
    "Accelerometer": Cls(
        base="Sensor",
        ro="value lookup_table",
        methods="getValues() getLookupTable()",
    ),
    "InertialUnit": Cls(
        base="Sensor",
        ro="roll_pitch_yaw quaternion noise",
        methods="getRollPitchYaw() getQuaternion() getNoise()",
    ),
    "Compass": Cls(
        base="Sensor",
        ro="value lookup_table",
        methods="getValues() getLookupTable()",
    ),
    "RangeFinder": Cls(
        base="Sensor",
        ro="range_image fov width height max_range min_range",
        methods=(
            "getRangeImage(data_type='list') getRangeImageArray() saveImage(filename,quality) getFov() getWidth() "
            "getHeight() getMinRange() getMaxRange()"
        ),
        static="rangeImageGetDepth(image,width,x,y)",
    ),
    "Display": Cls(
        base="Device",
        consts="RGB=3 RGBA=4 ARGB=5 BGRA=6 ABGR=7",
        ro="width height",
        wo="alpha color opacity",
        methods=(
            "__init__(name) getWidth() getHeight() setColor(color) setAlpha(alpha) setOpacity(opacity) "
            "setFont(font,size,anti_aliasing) attachCamera(camera) detachCamera() drawPixel(x,y) "
            "drawLine(x1,y1,x2,y2) drawRectangle(x,y,width,height) drawOval(cx,cy,a,b) drawPolygon(x,y) "
            "drawText(text,x,y) fillRectangle(x,y,width,height) fillOval(cx,cy,a,b) fillPolygon(x,y) "
            "imageNew(data,format,width,height) imageLoad(filename) imageCopy(x,y,width,height) "
            "imagePaste(image,x,y,blend) imageSave(image,filename) imageDelete(image)"
        ),
    ),
    "LED": Cls(
        base="Device",
        rw="value",
        methods="__init__(name) set(v) get()",
    ),
    "Pen": Cls(
        base="Device",
        importable=False,  # Webots' controller/__init__.py does not import Pen (controller.pen does)
        methods="__init__(name) write(write) setInkColor(color,density)",
    ),
    "Speaker": Cls(
        base="Device",
        methods=(
            "__init__(name) stop(sound=None) isSoundPlaying(sound) speak(text,volume) isSpeaking() "
            "setEngine(engine) setLanguage(language) getEngine() getLanguage()"
        ),
        static="playSound(left,right,sound,volume,pitch,balance,loop)",
    ),
    "LightSensor": Cls(
        base="Sensor",
        ro="value lookup_table",
        methods="getValue() getLookupTable()",
    ),
    "Altimeter": Cls(
        base="Sensor",
        ro="value",
        methods="getValue()",
    ),
    "Radar": Cls(
        base="Sensor",
        ro="max_range min_range horizontal_fov vertical_fov number_of_targets",
        methods=(
            "getTargets() getNumberOfTargets() getMinRange() getMaxRange() getHorizontalFov() getVerticalFov()"
        ),
    ),
    "RadarTarget": Cls(
        attr="distance receiver_power speed azimuth",
        methods="__init__(distance,receiver_power,speed,azimuth)",
    ),
    "VacuumGripper": Cls(
        base="Device",
        ro="on presence presence_sampling_period",
        methods=(
            "__init__(name) enablePresence(sampling_period) disablePresence() getPresence() "
            "getPresenceSamplingPeriod() isOn() turnOn() turnOff()"
        ),
    ),
    "Mouse": Cls(
        rw="sampling_period",
        methods=(
            "__init__(sampling_period=None) enable(p) disable() getSamplingPeriod() getState() enable3dPosition() "
            "disable3dPosition() is3dPositionEnabled()"
        ),
    ),
    "MouseState": Cls(
        attr="u v x y z left middle right",
        methods="__init__(u,v,x,y,z,left,middle,right)",
    ),
    "Joystick": Cls(
        ro="is_connected model number_of_axes number_of_povs pressed_button",
        rw="sampling_period",
        methods=(
            "__init__(sampling_period=None) enable(p) disable() getSamplingPeriod() isConnected() "
            "getNumberOfAxes() getAxisValue(axis) getNumberOfPovs() getPovValue(pov) getPressedButton() "
            "setConstantForce(level) setConstantForceDuration(duration) setAutoCenteringGain(gain) "
            "setResistanceGain(gain) setForceAxis(axis)"
        ),
    ),
    "Skin": Cls(
        base="Device",
        ro="bone_count",
        methods=(
            "__init__(name) getBoneCount() getBoneName(index) getBoneOrientation(index,absolute) "
            "getBonePosition(index,absolute) setBoneOrientation(index,orientation,absolute) "
            "setBonePosition(index,position,absolute)"
        ),
    ),
    "Motion": Cls(
        ro="duration",
        rw="time",
        methods=(
            "__init__(filename) isValid() play() stop() setLoop(loop) setReverse(reverse) isOver() getDuration() "
            "getTime() setTime(time)"
        ),
    ),
    "AnsiCodes": Cls(
        consts=(
            "RESET BOLD UNDERLINE BLACK_BACKGROUND RED_BACKGROUND GREEN_BACKGROUND YELLOW_BACKGROUND "
            "BLUE_BACKGROUND MAGENTA_BACKGROUND CYAN_BACKGROUND WHITE_BACKGROUND BLACK_FOREGROUND RED_FOREGROUND "
            "GREEN_FOREGROUND YELLOW_FOREGROUND BLUE_FOREGROUND MAGENTA_FOREGROUND CYAN_FOREGROUND "
            "WHITE_FOREGROUND CLEAR_SCREEN"
        ),
    ),
}

EXPORTS = sorted(name for name, cls in API.items() if cls.importable)


# ------------------------------------------------------------------------------------------ expected names


@dataclass(frozen=True)
class Expected:
    cls: str
    name: str
    kind: str  # export | const | attr | ro | rw | wo | method | static
    value: Any = None  # const: int value, or str (the type) for string constants
    params: tuple[tuple[str, Any], ...] = ()  # (name, default) with _REQUIRED for none

    @property
    def id(self) -> str:
        return f"{self.cls}.{self.name}" if self.kind != "export" else f"controller.{self.name}"


_REQUIRED = inspect.Parameter.empty


def _params(text: str) -> tuple[tuple[str, Any], ...]:
    out = []
    for item in filter(None, text.split(",")):
        name, _, default = item.partition("=")
        out.append((name, ast.literal_eval(default) if default else _REQUIRED))
    return tuple(out)


def _signatures(text: str) -> list[tuple[str, tuple[tuple[str, Any], ...]]]:
    out = []
    for token in text.split():
        name, _, rest = token.partition("(")
        out.append((name, _params(rest.rstrip(")"))))
    return out


def expected_names() -> list[Expected]:
    out = [Expected("controller", name, "export") for name in EXPORTS]
    for cls_name, cls in API.items():
        for token in cls.consts.split():
            name, _, value = token.partition("=")
            out.append(Expected(cls_name, name, "const", int(value) if value else str))
        for kind in ("attr", "ro", "rw", "wo"):
            out.extend(Expected(cls_name, name, kind) for name in getattr(cls, kind).split())
        for kind in ("methods", "static"):
            for name, params in _signatures(getattr(cls, kind)):
                out.append(Expected(cls_name, name, "method" if kind == "methods" else "static", params=params))
    out.extend(Expected("Robot", f"get{d}", "method", params=(("name", _REQUIRED),)) for d in DEPRECATED_GETTERS)
    return out


EXPECTED = expected_names()


# ------------------------------------------------------------------------------------------ checking


def _module() -> types.ModuleType:
    return importlib.import_module("dualtwin.webots.controller")


def _shim() -> types.ModuleType:
    return importlib.import_module("dualtwin.webots.shim.controller")


_MISSING = object()


def _annotated(cls: type, name: str) -> bool:
    return any(name in vars(k).get("__annotations__", {}) for k in cls.__mro__)


def _signature_problem(func: Any, want: tuple[tuple[str, Any], ...], drop_first: bool) -> str | None:
    try:
        params = list(inspect.signature(func).parameters.values())
    except (TypeError, ValueError):
        return "no inspectable signature"
    if drop_first:
        if not params or params[0].kind not in (params[0].POSITIONAL_ONLY, params[0].POSITIONAL_OR_KEYWORD):
            return "no self parameter"
        params = params[1:]
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    rest = [p for p in params if p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    got = tuple((p.name, p.default) for p in positional)
    if [n for n, _ in got] != [n for n, _ in want]:
        return f"parameters {[n for n, _ in got]}, Webots has {[n for n, _ in want]}"
    for (name, default), (_, wanted) in zip(got, want, strict=True):
        if repr(default) != repr(wanted) or type(default) is not type(wanted):
            shown = "none" if wanted is _REQUIRED else repr(wanted)
            return f"parameter {name!r} default {'none' if default is _REQUIRED else repr(default)}, Webots: {shown}"
    for p in rest:
        if p.kind is not p.KEYWORD_ONLY or p.default is _REQUIRED:
            return f"extra parameter {p}: only keyword-only parameters with a default may be added"
    return None


def problem(module: types.ModuleType, exp: Expected) -> str | None:
    """Why ``exp`` does not match on ``module`` (None: it matches)."""
    if exp.kind == "export":
        obj = getattr(module, exp.name, _MISSING)
        return None if inspect.isclass(obj) else f"`from controller import {exp.name}` fails"
    cls = getattr(module, exp.cls, _MISSING)
    if not inspect.isclass(cls):
        return f"class {exp.cls} is missing"
    raw = _MISSING
    for klass in cls.__mro__:
        if exp.name in vars(klass):
            raw = vars(klass)[exp.name]
            break
    if exp.kind == "attr":
        if isinstance(raw, property) or hasattr(raw, "__set__"):
            return "a property/descriptor, Webots has a plain attribute"
        if raw is _MISSING and not _annotated(cls, exp.name):
            return "missing (neither a class attribute nor an annotated instance attribute)"
        return None
    if raw is _MISSING:
        return "missing"
    if exp.kind == "const":
        if isinstance(raw, (property, staticmethod, classmethod, types.FunctionType)):
            return f"{type(raw).__name__}, Webots has a constant"
        if exp.value is str:
            return None if isinstance(raw, str) else f"constant {raw!r} is not a str"
        if type(raw) is not int or raw != exp.value:
            return f"constant {raw!r}, Webots: {exp.value}"
        return None
    if exp.kind in ("ro", "rw", "wo"):
        if not isinstance(raw, property):
            return f"{type(raw).__name__}, Webots has a property"
        kind = {(True, False): "ro", (True, True): "rw", (False, True): "wo"}.get(
            (raw.fget is not None, raw.fset is not None), "?")
        names = {"ro": "read-only", "rw": "settable", "wo": "write-only", "?": "broken"}
        return None if kind == exp.kind else f"{names[kind]} property, Webots: {names[exp.kind]}"
    if exp.kind == "static":
        if not isinstance(raw, staticmethod):
            return f"{type(raw).__name__}, Webots has a staticmethod"
        return _signature_problem(raw.__func__, exp.params, drop_first=False)
    if not isinstance(raw, types.FunctionType):
        return f"{type(raw).__name__}, Webots has a method"
    return _signature_problem(raw, exp.params, drop_first=True)


def api_report(module: types.ModuleType | None = None) -> tuple[int, int, dict[str, str]]:
    """(names that match, names in the table, {name id: problem}) for ``module`` (default: ours)."""
    module = module or _module()
    shim = _shim()
    problems = {}
    for exp in EXPECTED:
        why = problem(shim if exp.kind == "export" else module, exp)
        if why is not None:
            problems[exp.id] = why
    return len(EXPECTED) - len(problems), len(EXPECTED), problems


# ------------------------------------------------------------------------------------------ tests


def test_table_counts_846_names() -> None:
    """The encoding holds exactly Webots' 846 names, 38 importable classes, no name twice."""
    assert len(EXPECTED) == TOTAL
    assert len(EXPORTS) == 38
    assert len({e.id for e in EXPECTED}) == TOTAL


@pytest.mark.parametrize("exp", EXPECTED, ids=lambda e: e.id)
def test_name(exp: Expected) -> None:
    module = _shim() if exp.kind == "export" else _module()
    why = problem(module, exp)
    assert why is None, f"{exp.id} ({exp.kind}): {why}"
    # a controller imports the shim's classes: when they are not ours (proxies), they must match too
    if exp.kind != "export":
        shim_cls = getattr(_shim(), exp.cls, None)
        if inspect.isclass(shim_cls) and shim_cls is not getattr(module, exp.cls, None):
            why = problem(_shim(), exp)
            assert why is None, f"controller.{exp.id} ({exp.kind}): {why}"


@pytest.mark.parametrize("name", [n for n, c in API.items() if c.base], ids=str)
def test_inheritance(name: str) -> None:
    """Webots' class tree: a DistanceSensor is a Sensor is a Device, a Supervisor is a Robot."""
    module = _module()
    cls, base = getattr(module, name, None), getattr(module, API[name].base, None)
    assert inspect.isclass(cls) and inspect.isclass(base), f"{name} or {API[name].base} missing"
    assert issubclass(cls, base), f"{name} does not inherit {API[name].base}"


def test_api_figure(capsys: pytest.CaptureFixture[str]) -> None:
    matched, total, problems = api_report()
    with capsys.disabled():
        print(f"\nWebots R2023b Python API: {matched}/{total} names match")
    assert total == TOTAL
    assert matched == total, f"{len(problems)} names differ, first: {sorted(problems.items())[:5]}"


if __name__ == "__main__":
    matched, total, problems = api_report()
    for key, why in sorted(problems.items()):
        print(f"{key}: {why}")
    print(f"{matched}/{total} names match")
