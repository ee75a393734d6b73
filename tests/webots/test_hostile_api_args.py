"""Hostile numbers passed to the controller API: refused at the call (an exception there, as Webots' ctypes
raises, or an error line) and never stored to break a later step.

R = /work/shared/reference/webots-python-api.md ("Arguments": integers go to C unchanged; the C functions take an
``int``), D = .../webots-devices.md §12 (a Python ``int`` is passed raw: beyond a C long ctypes raises)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualtwin.webots.controller import Supervisor
from tests.support.quiet_worlds import quiet_supervisor

TS = 4
WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} gravity 0 }}
Robot {{ supervisor TRUE children [
  HingeJoint {{ jointParameters HingeJointParameters {{ axis 0 1 0 }}
    device [ RotationalMotor {{ name "m" }} PositionSensor {{ name "s" }} ]
    endPoint Solid {{ translation 0.5 0 0 boundingObject Sphere {{ radius 0.05 }} physics Physics {{ }} }} }}
  GPS {{ name "gps" }}
] }}
"""


def _sup() -> Supervisor:
    return quiet_supervisor(WORLD)


HUGE = [10**400, 2**31, -(2**31) - 1, np.int64(2**40)]


@pytest.mark.parametrize("period", HUGE, ids=["1e400", "2**31", "-2**31-1", "int64 2**40"])
@pytest.mark.parametrize("call", ["s.enable", "gps.enable", "m.enableForceFeedback", "m.enableTorqueFeedback"])
def test_a_period_beyond_a_c_int_is_refused_at_the_call(call: str, period: object) -> None:
    # it was stored, and the next step's sampling test raised OverflowError (10**400) from inside the step
    sup = _sup()
    name, method = call.split(".")
    device = sup.getDevice(name)
    with pytest.raises(TypeError, match=r"expects a whole number within a C int"):
        getattr(device, method)(period)
    for _ in range(3):
        assert sup.step(TS) != -1
    getter = "getForceFeedbackSamplingPeriod" if "Force" in method else (
        "getTorqueFeedbackSamplingPeriod" if "Torque" in method else "getSamplingPeriod")
    assert getattr(device, getter)() == 0  # not enabled


def test_periods_within_a_c_int_are_kept() -> None:
    sup = _sup()
    s = sup.getDevice("s")
    s.enable(2**31 - 1)
    assert s.getSamplingPeriod() == 2**31 - 1
    assert sup.step(TS) != -1 and math.isnan(s.getValue())  # its first sample is 24 days away
    s.enable(np.int64(TS))
    assert sup.step(TS) != -1 and s.getValue() == pytest.approx(0.0, abs=1e-9)
