"""Thin ctypes binding to the system Open Dynamics Engine (``libode.so.8``, Debian ``libode8``).

Only the calls the Webots twin needs are declared. Every pointer argument is declared ``c_void_p`` so
callers can pass plain integer handles (fast) or ctypes arrays/structures; ``dReal`` is ``double``
because Webots uses a double-precision ODE (docs/reference/webots-on-ode.md §1.5, Appendix A.1) and
:func:`load` refuses a single-precision build.

Struct layouts (``dMass``, ``dContactGeom``, ``dSurfaceParameters``, ``dContact``) and enum values
follow the ODE 0.16 headers for ``dDOUBLE``.

Note: the Debian build keeps ODE's internal assertions (its configuration string has no
``ODE_EXT_no_debug``), so an invalid call aborts the process. Callers must never pass NULL where ODE
asserts a body (e.g. ``dAreConnectedExcluding(b, NULL, ...)``, spec Appendix A.8) and must stop
stepping once the state is non-finite.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import threading
from collections.abc import Callable
from ctypes import CFUNCTYPE, POINTER, Structure, c_char_p, c_double, c_int, c_uint, c_ulong, c_void_p
from pathlib import Path
from typing import Any

import numpy as np

from dualtwin.errors import DualtwinError
from dualtwin.native_build import compile_library, library_path

dReal = c_double
dVector3 = c_double * 4
dVector4 = c_double * 4
dMatrix3 = c_double * 12
dQuaternion = c_double * 4

dInfinity = float("inf")

# dContact surface mode flags (contact.h)
dContactMu2 = 0x001
dContactAxisDep = 0x001
dContactFDir1 = 0x002
dContactBounce = 0x004
dContactSoftERP = 0x008
dContactSoftCFM = 0x010
dContactMotion1 = 0x020
dContactMotion2 = 0x040
dContactMotionN = 0x080
dContactSlip1 = 0x100
dContactSlip2 = 0x200
dContactRolling = 0x400
dContactApprox0 = 0x0000
dContactApprox1_1 = 0x1000
dContactApprox1_2 = 0x2000
dContactApprox1_N = 0x4000
dContactApprox1 = 0x7000

# joint parameters (common.h, D_ALL_PARAM_NAMES; groups 2 and 3 start at 0x100 and 0x200)
dParamLoStop = 0
dParamHiStop = 1
dParamVel = 2
dParamLoVel = 3
dParamHiVel = 4
dParamFMax = 5
dParamFudgeFactor = 6
dParamBounce = 7
dParamCFM = 8
dParamStopERP = 9
dParamStopCFM = 10
dParamSuspensionERP = 11
dParamSuspensionCFM = 12
dParamERP = 13
dParamGroup2 = 0x100
dParamGroup3 = 0x200

# joint types (common.h)
dJointTypeNone = 0
dJointTypeBall = 1
dJointTypeHinge = 2
dJointTypeSlider = 3
dJointTypeContact = 4
dJointTypeUniversal = 5
dJointTypeHinge2 = 6
dJointTypeFixed = 7
dJointTypeNull = 8
dJointTypeAMotor = 9
dJointTypeLMotor = 10

dAMotorUser = 0
dAMotorEuler = 1

# geom classes (collision.h)
dSphereClass = 0
dBoxClass = 1
dCapsuleClass = 2
dCylinderClass = 3
dPlaneClass = 4
dRayClass = 5
dConvexClass = 6
dGeomTransformClass = 7
dTriMeshClass = 8
dHeightfieldClass = 9
dSimpleSpaceClass = 10


class dMass(Structure):
    _fields_ = [("mass", c_double), ("c", dVector3), ("I", dMatrix3)]


class dSurfaceParameters(Structure):
    _fields_ = [
        ("mode", c_int),
        ("mu", c_double),
        ("mu2", c_double),
        ("rho", c_double),
        ("rho2", c_double),
        ("rhoN", c_double),
        ("bounce", c_double),
        ("bounce_vel", c_double),
        ("soft_erp", c_double),
        ("soft_cfm", c_double),
        ("motion1", c_double),
        ("motion2", c_double),
        ("motionN", c_double),
        ("slip1", c_double),
        ("slip2", c_double),
    ]


class dContactGeom(Structure):
    _fields_ = [
        ("pos", dVector3),
        ("normal", dVector3),
        ("depth", c_double),
        ("g1", c_void_p),
        ("g2", c_void_p),
        ("side1", c_int),
        ("side2", c_int),
    ]


class dContact(Structure):
    _fields_ = [("surface", dSurfaceParameters), ("geom", dContactGeom), ("fdir1", dVector3)]


class dJointFeedback(Structure):
    _fields_ = [("f1", dVector3), ("t1", dVector3), ("f2", dVector3), ("t2", dVector3)]


NearCallback = CFUNCTYPE(None, c_void_p, c_void_p, c_void_p)

P = c_void_p
D = c_double
I = c_int  # noqa: E741 - short aliases keep the signature table readable

# name -> (restype, argtypes)
_SIGNATURES: dict[str, tuple[Any, list[Any]]] = {
    # init / config
    "dInitODE2": (c_int, [c_uint]),
    "dAllocateODEDataForThread": (c_int, [c_uint]),
    "dCloseODE": (None, []),
    "dCheckConfiguration": (c_int, [c_char_p]),
    "dGetConfiguration": (c_char_p, []),
    "dRandSetSeed": (None, [c_ulong]),
    "dRandGetSeed": (c_ulong, []),
    # world
    "dWorldCreate": (P, []),
    "dWorldDestroy": (None, [P]),
    "dWorldSetGravity": (None, [P, D, D, D]),
    "dWorldGetGravity": (None, [P, P]),
    "dWorldSetERP": (None, [P, D]),
    "dWorldGetERP": (D, [P]),
    "dWorldSetCFM": (None, [P, D]),
    "dWorldGetCFM": (D, [P]),
    "dWorldSetDamping": (None, [P, D, D]),
    "dWorldSetLinearDampingThreshold": (None, [P, D]),
    "dWorldSetAngularDampingThreshold": (None, [P, D]),
    "dWorldSetAutoDisableFlag": (None, [P, I]),
    "dWorldSetAutoDisableTime": (None, [P, D]),
    "dWorldSetAutoDisableSteps": (None, [P, I]),
    "dWorldSetAutoDisableLinearThreshold": (None, [P, D]),
    "dWorldSetAutoDisableAngularThreshold": (None, [P, D]),
    "dWorldSetContactSurfaceLayer": (None, [P, D]),
    "dWorldSetContactMaxCorrectingVel": (None, [P, D]),
    "dWorldStep": (c_int, [P, D]),
    # spaces
    "dSimpleSpaceCreate": (P, [P]),
    "dSpaceDestroy": (None, [P]),
    "dSpaceAdd": (None, [P, P]),
    "dSpaceRemove": (None, [P, P]),
    "dSpaceSetCleanup": (None, [P, I]),
    "dSpaceGetNumGeoms": (c_int, [P]),
    "dSpaceGetGeom": (P, [P, I]),
    "dSpaceCollide": (None, [P, P, P]),
    "dSpaceCollide2": (None, [P, P, P, P]),
    # bodies
    "dBodyCreate": (P, [P]),
    "dBodyDestroy": (None, [P]),
    "dBodySetPosition": (None, [P, D, D, D]),
    "dBodySetRotation": (None, [P, P]),
    "dBodySetQuaternion": (None, [P, P]),
    "dBodySetLinearVel": (None, [P, D, D, D]),
    "dBodySetAngularVel": (None, [P, D, D, D]),
    "dBodyGetPosition": (P, [P]),
    "dBodyGetRotation": (P, [P]),
    "dBodyGetQuaternion": (P, [P]),
    "dBodyGetLinearVel": (P, [P]),
    "dBodyGetAngularVel": (P, [P]),
    "dBodySetMass": (None, [P, P]),
    "dBodyGetMass": (None, [P, P]),
    "dBodyAddForce": (None, [P, D, D, D]),
    "dBodyAddTorque": (None, [P, D, D, D]),
    "dBodyAddForceAtPos": (None, [P, D, D, D, D, D, D]),
    "dBodySetForce": (None, [P, D, D, D]),
    "dBodySetTorque": (None, [P, D, D, D]),
    "dBodyGetForce": (P, [P]),
    "dBodyGetTorque": (P, [P]),
    "dBodyEnable": (None, [P]),
    "dBodyDisable": (None, [P]),
    "dBodyIsEnabled": (c_int, [P]),
    "dBodySetAutoDisableFlag": (None, [P, I]),
    "dBodySetAutoDisableLinearThreshold": (None, [P, D]),
    "dBodySetAutoDisableAngularThreshold": (None, [P, D]),
    "dBodySetAutoDisableTime": (None, [P, D]),
    "dBodySetAutoDisableSteps": (None, [P, I]),
    "dBodySetAutoDisableAverageSamplesCount": (None, [P, c_uint]),
    "dBodySetDamping": (None, [P, D, D]),
    "dBodySetDampingDefaults": (None, [P]),
    "dBodySetMaxAngularSpeed": (None, [P, D]),
    "dBodyGetNumJoints": (c_int, [P]),
    "dBodyGetJoint": (P, [P, I]),
    "dBodyGetRelPointPos": (None, [P, D, D, D, P]),
    "dBodyGetPosRelPoint": (None, [P, D, D, D, P]),
    "dBodyVectorToWorld": (None, [P, D, D, D, P]),
    "dBodyVectorFromWorld": (None, [P, D, D, D, P]),
    "dBodySetGravityMode": (None, [P, I]),
    # mass
    "dMassSetZero": (None, [P]),
    "dMassCheck": (c_int, [P]),
    "dMassSetParameters": (None, [P, D, D, D, D, D, D, D, D, D, D]),
    "dMassSetSphere": (None, [P, D, D]),
    "dMassSetBox": (None, [P, D, D, D, D]),
    "dMassSetCylinder": (None, [P, D, I, D, D]),
    "dMassSetCapsule": (None, [P, D, I, D, D]),
    "dMassSetTrimesh": (None, [P, D, P]),
    "dMassAdjust": (None, [P, D]),
    "dMassTranslate": (None, [P, D, D, D]),
    "dMassRotate": (None, [P, P]),
    "dMassAdd": (None, [P, P]),
    # geoms
    "dCreateBox": (P, [P, D, D, D]),
    "dCreateSphere": (P, [P, D]),
    "dCreateCylinder": (P, [P, D, D]),
    "dCreateCapsule": (P, [P, D, D]),
    "dCreatePlane": (P, [P, D, D, D, D]),
    "dGeomDestroy": (None, [P]),
    "dGeomSetBody": (None, [P, P]),
    "dGeomGetBody": (P, [P]),
    "dGeomSetPosition": (None, [P, D, D, D]),
    "dGeomSetRotation": (None, [P, P]),
    "dGeomGetPosition": (P, [P]),
    "dGeomGetRotation": (P, [P]),
    "dGeomSetOffsetWorldPosition": (None, [P, D, D, D]),
    "dGeomSetOffsetWorldRotation": (None, [P, P]),
    "dGeomGetOffsetPosition": (P, [P]),
    "dGeomSetCategoryBits": (None, [P, c_ulong]),
    "dGeomSetCollideBits": (None, [P, c_ulong]),
    "dGeomGetClass": (c_int, [P]),
    "dGeomGetAABB": (None, [P, P]),
    "dGeomEnable": (None, [P]),
    "dGeomDisable": (None, [P]),
    "dGeomPlaneSetParams": (None, [P, D, D, D, D]),
    "dGeomPlaneGetParams": (None, [P, P]),
    "dGeomBoxGetLengths": (None, [P, P]),
    "dGeomSphereGetRadius": (D, [P]),
    "dGeomCylinderGetParams": (None, [P, P, P]),
    "dGeomCapsuleGetParams": (None, [P, P, P]),
    "dGeomBoxSetLengths": (None, [P, D, D, D]),
    "dGeomSphereSetRadius": (None, [P, D]),
    "dGeomCylinderSetParams": (None, [P, D, D]),
    "dGeomCapsuleSetParams": (None, [P, D, D]),
    "dGeomTriMeshSetData": (None, [P, P]),
    # rays (distance sensors, lidars, range finders)
    "dCreateRay": (P, [P, D]),
    "dGeomRaySet": (None, [P, D, D, D, D, D, D]),
    "dGeomRaySetLength": (None, [P, D]),
    "dGeomRayGetLength": (D, [P]),
    "dGeomRayGet": (None, [P, P, P]),
    "dGeomRaySetParams": (None, [P, I, I]),
    "dGeomRaySetClosestHit": (None, [P, I]),
    "dGeomTriMeshDataCreate": (P, []),
    "dGeomTriMeshDataDestroy": (None, [P]),
    "dGeomTriMeshDataBuildDouble": (None, [P, P, I, I, P, I, I]),
    "dCreateTriMesh": (P, [P, P, P, P, P]),
    "dGeomHeightfieldDataCreate": (P, []),
    "dGeomHeightfieldDataDestroy": (None, [P]),
    "dGeomHeightfieldDataBuildDouble": (None, [P, P, I, D, D, I, I, D, D, D, I]),
    "dGeomHeightfieldDataSetBounds": (None, [P, D, D]),
    "dCreateHeightfield": (P, [P, P, I]),
    "dGeomHeightfieldSetHeightfieldData": (None, [P, P]),
    "dCollide": (c_int, [P, P, I, P, I]),
    # joints
    "dJointGroupCreate": (P, [I]),
    "dJointGroupDestroy": (None, [P]),
    "dJointGroupEmpty": (None, [P]),
    "dJointCreateContact": (P, [P, P, P]),
    "dJointCreateHinge": (P, [P, P]),
    "dJointCreateSlider": (P, [P, P]),
    "dJointCreateBall": (P, [P, P]),
    "dJointCreateHinge2": (P, [P, P]),
    "dJointCreateFixed": (P, [P, P]),
    "dJointCreateAMotor": (P, [P, P]),
    "dJointCreateLMotor": (P, [P, P]),
    "dJointDestroy": (None, [P]),
    "dJointAttach": (None, [P, P, P]),
    "dJointGetBody": (P, [P, I]),
    "dJointGetType": (c_int, [P]),
    "dJointSetFeedback": (None, [P, P]),
    "dJointGetFeedback": (P, [P]),
    "dJointSetHingeAnchor": (None, [P, D, D, D]),
    "dJointSetHingeAxis": (None, [P, D, D, D]),
    "dJointGetHingeAnchor": (None, [P, P]),
    "dJointGetHingeAxis": (None, [P, P]),
    "dJointGetHingeAngle": (D, [P]),
    "dJointGetHingeAngleRate": (D, [P]),
    "dJointSetHingeParam": (None, [P, I, D]),
    "dJointGetHingeParam": (D, [P, I]),
    "dJointAddHingeTorque": (None, [P, D]),
    "dJointSetSliderAxis": (None, [P, D, D, D]),
    "dJointGetSliderAxis": (None, [P, P]),
    "dJointGetSliderPosition": (D, [P]),
    "dJointGetSliderPositionRate": (D, [P]),
    "dJointSetSliderParam": (None, [P, I, D]),
    "dJointGetSliderParam": (D, [P, I]),
    "dJointAddSliderForce": (None, [P, D]),
    "dJointSetBallAnchor": (None, [P, D, D, D]),
    "dJointSetHinge2Anchor": (None, [P, D, D, D]),
    "dJointSetHinge2Axes": (None, [P, P, P]),
    "dJointGetHinge2Angle1": (D, [P]),
    "dJointGetHinge2Angle2": (D, [P]),
    "dJointGetHinge2Angle1Rate": (D, [P]),
    "dJointGetHinge2Axis1": (None, [P, P]),
    "dJointGetHinge2Axis2": (None, [P, P]),
    "dJointGetBallAnchor": (None, [P, P]),
    "dJointGetHinge2Angle2Rate": (D, [P]),
    "dJointSetHinge2Param": (None, [P, I, D]),
    "dJointAddHinge2Torques": (None, [P, D, D]),
    "dJointSetFixed": (None, [P]),
    "dJointSetAMotorMode": (None, [P, I]),
    "dJointSetAMotorNumAxes": (None, [P, I]),
    "dJointSetAMotorAxis": (None, [P, I, I, D, D, D]),
    "dJointSetAMotorAngle": (None, [P, I, D]),
    "dJointSetAMotorParam": (None, [P, I, D]),
    "dJointGetAMotorAngle": (D, [P, I]),
    "dJointGetAMotorAngleRate": (D, [P, I]),
    "dJointGetAMotorAxis": (None, [P, I, P]),
    "dJointGetAMotorParam": (D, [P, I]),
    "dJointAddAMotorTorques": (None, [P, D, D, D]),
    "dJointSetLMotorNumAxes": (None, [P, I]),
    "dJointSetLMotorAxis": (None, [P, I, I, D, D, D]),
    "dJointSetLMotorParam": (None, [P, I, D]),
    "dAreConnectedExcluding": (c_int, [P, P, I]),
}

_LIB: ctypes.CDLL | None = None

_CANDIDATE_NAMES = ("libode.so.8", "libode.so", "libode.so.6", "libode.so.3")


class OdeUnavailableError(DualtwinError, RuntimeError):
    """The ODE shared library is missing or unsuitable: the user's fix (install ``libode8``), so a user error
    (one line from the CLI); still a RuntimeError for callers that catch it as one."""


def _open() -> ctypes.CDLL:
    names = list(_CANDIDATE_NAMES)
    found = ctypes.util.find_library("ode")
    if found:
        names.insert(0, found)
    errors = []
    for name in names:
        try:
            return ctypes.CDLL(name)
        except OSError as exc:
            errors.append(f"{name}: {exc}")
    raise OdeUnavailableError(
        "Open Dynamics Engine shared library not found (tried "
        + ", ".join(names)
        + "). Install the Debian package 'libode8' (apt-get install libode8)."
    )


# The calls that keep releasing the GIL: the world step (tens of microseconds to milliseconds) and the collision
# pass, which calls back into Python for every candidate pair. Every other call is a short query or setter: made
# through a ``PyDLL`` handle on the same library it keeps the GIL, which saves the release and re-acquisition
# (about 0.1 µs of some 0.5 µs per call; the step loop makes dozens per basic step). Nothing in ODE waits on
# another thread, so holding the GIL through such a call can block no one for longer than the call.
_RELEASE_GIL = frozenset({"dWorldStep", "dSpaceCollide", "dSpaceCollide2"})


def load() -> ctypes.CDLL:
    """Open, configure and initialise ``libode`` once; return the library handle.

    Raises:
        OdeUnavailableError: the library is missing or not built in double precision.
    """
    global _LIB
    if _LIB is not None:
        return _LIB
    lib = _open()
    quick = ctypes.PyDLL(lib._name)  # the same library (dlopen hands back the loaded one), GIL kept in calls
    for name, (restype, argtypes) in _SIGNATURES.items():
        try:
            fn = getattr(lib, name)
        except AttributeError as exc:
            raise OdeUnavailableError(f"libode lacks {name}: an ODE >= 0.16 build is required") from exc
        if name not in _RELEASE_GIL:
            fn = getattr(quick, name)
            setattr(lib, name, fn)  # what ``lib.<name>`` answers from now on
        fn.restype = restype
        fn.argtypes = argtypes
    lib.dInitODE2(0)
    if not lib.dCheckConfiguration(b"ODE_double_precision"):
        raise OdeUnavailableError(
            "libode is not built in double precision; Webots uses dDOUBLE (spec Appendix A.1)"
        )
    _LIB = lib
    ensure_thread()
    return lib


_THREADS = threading.local()


def ensure_thread() -> None:
    """Allocate ODE's per-thread data (collision included) for the calling thread, once.

    ODE requires ``dAllocateODEDataForThread`` in every thread that steps or collides; controllers run
    by :mod:`dualtwin.webots.runner` may step the simulation from their own threads.
    """
    if getattr(_THREADS, "ready", False):
        return
    lib = load()
    # 0xFFFFFFFF = dAllocateMaskAll: collision and step data for this thread.
    if not lib.dAllocateODEDataForThread(0xFFFFFFFF):
        raise OdeUnavailableError("dAllocateODEDataForThread failed")
    _THREADS.ready = True


GUARD_SOURCE = Path(__file__).with_name("native") / "ode_guard.c"
_guard_lock = threading.Lock()
_guard: tuple[Any, int] | None = None
_guard_failure: str | None = None


class OdeStepError(DualtwinError):
    """ODE stopped inside a guarded world step on an internal error (its message); the world is half stepped."""


def guarded_step() -> Callable[[int, float], None] | None:
    """A world step that raises :class:`OdeStepError` where ODE would abort the process (``native/ode_guard.c``,
    compiled once with the system C compiler), or None where it cannot be had (:func:`guard_failure` says why;
    ``DUALTWIN_ODE_GUARD=0`` turns it off): the caller then steps with ``dWorldStep`` as before."""
    global _guard, _guard_failure
    with _guard_lock:
        if _guard is None and _guard_failure is None:
            if os.environ.get("DUALTWIN_ODE_GUARD", "1") == "0":
                _guard_failure = "turned off by DUALTWIN_ODE_GUARD=0"
            else:
                try:
                    _guard = _load_guard(load())
                except (DualtwinError, OSError, AttributeError) as exc:
                    _guard_failure = str(exc)
        if _guard is None:
            return None
        call, step = _guard
    message = ctypes.create_string_buffer(512)

    def guarded(world: int, stepsize: float) -> None:
        if call(step, world, stepsize, message, len(message)) != 0:
            raise OdeStepError(message.value.decode(errors="replace").strip())

    return guarded


def guard_failure() -> str | None:
    """Why :func:`guarded_step` gave None (None when it has not been asked, or gave a step)."""
    return _guard_failure


def _load_guard(lib: ctypes.CDLL) -> tuple[Any, int]:
    shim = ctypes.CDLL(str(compile_library(GUARD_SOURCE, library_path(GUARD_SOURCE, "ode_guard"),
                                           what="the ODE step guard")))
    raw = ctypes.CDLL(lib._name)  # (the loaded library again) plain function addresses for the shim
    install = shim.dualtwin_ode_guard_install
    install.restype, install.argtypes = None, [c_void_p, c_void_p]
    install(ctypes.cast(raw.dSetDebugHandler, c_void_p), ctypes.cast(raw.dSetErrorHandler, c_void_p))
    call = shim.dualtwin_guarded_step  # a CDLL call: the GIL is released for the step, as for dWorldStep
    call.restype, call.argtypes = c_int, [c_void_p, c_void_p, c_double, c_char_p, c_int]
    address = ctypes.cast(raw.dWorldStep, c_void_p).value
    assert address is not None
    return call, address


def configuration() -> str:
    """ODE's build configuration string (e.g. ``"ODE ODE_EXT_trimesh ... ODE_double_precision"``)."""
    raw = load().dGetConfiguration()
    return raw.decode() if raw else ""


def vec3(ptr: int) -> Any:
    """A live ``double[3]`` view of an ODE-owned vector (e.g. the result of ``dBodyGetPosition``).

    The memory belongs to the ODE object and stays valid while it exists; reading the view costs no
    ctypes call, which keeps per-step state checks cheap.
    """
    return (c_double * 3).from_address(ptr)


def vec4(ptr: int) -> Any:
    """A live ``double[4]`` view (quaternion) of ODE-owned memory."""
    return (c_double * 4).from_address(ptr)


def mat3(ptr: int) -> Any:
    """A live ``double[12]`` view of an ODE ``dMatrix3`` (3 rows of 4, the 4th column is padding)."""
    return (c_double * 12).from_address(ptr)


def primitive_size(lib: Any, geom: Any, cls: int) -> tuple[float, ...] | None:
    """A primitive geom's dimensions, as the bounding shapes use them: a box's half-extents ``(hx, hy, hz)``, a
    sphere's ``(radius,)``, a capsule's or cylinder's ``(radius, half length along its z axis)`` (a capsule's
    caps not counted); None for any other ODE class (``cls``, from ``dGeomGetClass``)."""
    if cls == dBoxClass:
        lengths = (c_double * 4)()
        lib.dGeomBoxGetLengths(geom, lengths)
        return lengths[0] / 2, lengths[1] / 2, lengths[2] / 2
    if cls == dSphereClass:
        return (float(lib.dGeomSphereGetRadius(geom)),)
    if cls in (dCapsuleClass, dCylinderClass):
        radius, length = c_double(), c_double()
        (lib.dGeomCapsuleGetParams if cls == dCapsuleClass else lib.dGeomCylinderGetParams)(
            geom, ctypes.byref(radius), ctypes.byref(length))
        return radius.value, length.value / 2
    return None


def geom_pose(lib: Any, geom: Any) -> tuple[tuple[float, float, float], tuple[float, ...]]:
    """A placeable geom's world position and its row-major 3×3 rotation (9 values), read now."""
    p = vec3(lib.dGeomGetPosition(geom))
    r = mat3(lib.dGeomGetRotation(geom))
    return (p[0], p[1], p[2]), (r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10])


def matrix3(rows: Any) -> Any:
    """Pack a row-major 3×3 rotation (nested sequences) into a ``dMatrix3``."""
    m = dMatrix3()
    for i in range(3):
        for j in range(3):
            m[4 * i + j] = float(rows[i][j])
    return m


DOUBLE_P = POINTER(c_double)


def build_trimesh_data(vertices: Any, triangles: Any) -> tuple[Any, ...]:
    """ODE triangle-mesh data (``dGeomTriMeshDataBuildDouble``) of ``vertices`` (n, 3) and ``triangles`` (m, 3).

    Returns ``(data, vertex array, index array)``: ODE keeps pointers into the arrays, so the tuple must be kept
    as long as the data (and any trimesh made from it) lives. ``dGeomTriMeshDataDestroy(data)`` frees it.
    """
    verts = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
    index = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
    lib = load()
    data = lib.dGeomTriMeshDataCreate()
    lib.dGeomTriMeshDataBuildDouble(data, verts.ctypes.data, 3 * 8, len(verts), index.ctypes.data, index.size, 3 * 4)
    return data, verts, index
