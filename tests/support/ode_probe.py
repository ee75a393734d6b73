"""ODE getters the twin itself never calls, bound on a handle of its own to the same ``libode`` (the twin's
ctypes signatures are left as they are), to read the world, space, body and contact-joint state a Simulation
set up: the tests of the specification's world set-up, contacts and bodies read ODE through these."""

from __future__ import annotations

import contextlib
import ctypes
import warnings
from collections.abc import Callable, Iterator
from ctypes import POINTER, c_double, c_int, c_void_p
from typing import Any

from dualtwin.webots import load_world_text, ode
from dualtwin.webots.physics import Simulation

__all__ = ["contact_joints", "probe", "simulations"]


@contextlib.contextmanager
def simulations(default_info: str = "", *, quiet: bool = False) -> Iterator[Callable[..., Simulation]]:
    """``build(scene, info=default_info)``: a Simulation of ``scene`` (world nodes as text) under
    ``WorldInfo { info }``, closed when the block ends; ``quiet`` silences build warnings (read them from
    ``build_warnings``)."""
    sims: list[Simulation] = []

    def build(scene: str, info: str = default_info) -> Simulation:
        text = f"#VRML_SIM R2023b utf8\nWorldInfo {{ {info} }}\n{scene}\n"
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")
            sim = Simulation(load_world_text(text, "t.wbt"))
        sims.append(sim)
        return sim

    try:
        yield build
    finally:
        for sim in sims:
            sim.close()

P, D, N = c_void_p, c_double, c_int
_SIGNATURES: dict[str, tuple[Any, list[Any]]] = {
    "dWorldGetGravity": (None, [P, POINTER(c_double)]),
    "dWorldGetERP": (D, [P]),
    "dWorldGetCFM": (D, [P]),
    "dWorldGetLinearDamping": (D, [P]),
    "dWorldGetAngularDamping": (D, [P]),
    "dWorldGetLinearDampingThreshold": (D, [P]),
    "dWorldGetAngularDampingThreshold": (D, [P]),
    "dWorldGetContactSurfaceLayer": (D, [P]),
    "dWorldGetContactMaxCorrectingVel": (D, [P]),
    "dWorldGetAutoDisableFlag": (N, [P]),
    "dWorldGetAutoDisableTime": (D, [P]),
    "dWorldGetAutoDisableSteps": (N, [P]),
    "dSpaceGetClass": (N, [P]),
    "dGeomGetClass": (N, [P]),
    "dGeomGetBody": (P, [P]),
    "dGeomGetSpace": (P, [P]),
    "dBodyGetAutoDisableFlag": (N, [P]),
    "dBodyGetAutoDisableLinearThreshold": (D, [P]),
    "dBodyGetAutoDisableAngularThreshold": (D, [P]),
    "dBodyGetAutoDisableTime": (D, [P]),
    "dBodyGetAutoDisableSteps": (N, [P]),
    "dBodyGetLinearDamping": (D, [P]),
    "dBodyGetAngularDamping": (D, [P]),
    "dBodyGetMaxAngularSpeed": (D, [P]),
    "dBodyGetGyroscopicMode": (N, [P]),
    "dBodyGetNumJoints": (N, [P]),
    "dBodyGetJoint": (P, [P, N]),
    "dJointGetType": (N, [P]),
    "dJointGetBody": (P, [P, N]),
    "dJointGetHinge2Param": (D, [P, N]),
}
_LIB: Any = None
CONTACT_JOINT = 4  # dJointTypeContact


def probe() -> Any:
    """The getters above, on their own handle to the library the twin loaded."""
    global _LIB
    if _LIB is None:
        lib = ctypes.CDLL(ode.load()._name)
        for name, (restype, argtypes) in _SIGNATURES.items():
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = restype, argtypes
        _LIB = lib
    return _LIB


def contact_joints(body_ptr: int) -> list[tuple[int | None, int | None]]:
    """The contact joints attached to a body now, as their (body 0, body 1) pointers (None: the static world)."""
    lib = probe()
    out = []
    for i in range(lib.dBodyGetNumJoints(body_ptr)):
        j = lib.dBodyGetJoint(body_ptr, i)
        if lib.dJointGetType(j) == CONTACT_JOINT:
            out.append((lib.dJointGetBody(j, 0), lib.dJointGetBody(j, 1)))
    return out
