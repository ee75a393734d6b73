"""The converter's ODE -> MuJoCo equivalences, one function each, and the convert package's import order."""

from __future__ import annotations

import math

import grimp
import mujoco
import numpy as np
import pytest

from dualtwin.convert.equivalences import (
    INFINITE_FRICTION,
    apply_joint_dynamics,
    camera_rotation,
    contact_pair,
    contact_solref,
    coulomb_friction,
    hinge2_second_axis,
    hinge_stop_range,
    motor_numeric,
    rangefinder_rotation,
)
from dualtwin.geometry import axis_angle_matrix


def test_hinge_stops_are_clamped_into_plus_minus_pi_about_the_offset() -> None:
    assert hinge_stop_range(-4.0, 5.0) == (-math.pi, math.pi)
    assert hinge_stop_range(-1.0, 2.0) == (-1.0, 2.0)  # control: stops inside pass unchanged
    # ODE clamps -maxStop + offset and -minStop + offset: about the initial position, not about 0 (§4.2)
    assert hinge_stop_range(-3.0, 3.0, 1.0) == (1.0 - math.pi, 3.0)


def test_coulomb_friction_first_value_and_infinite() -> None:
    assert coulomb_friction({"coulombFriction": [-1.0]}) == INFINITE_FRICTION
    assert coulomb_friction({"coulombFriction": [0.7, 0.2]}) == 0.7
    assert coulomb_friction({}) == 1.0


def test_contact_pair_uses_the_softness_mapping() -> None:
    props = {"coulombFriction": [0.5], "softERP": 0.3, "softCFM": 0.002}
    mu, solref, solimp = contact_pair(props, 2.0, 0.016, 0.002)
    timeconst, dampratio, d = contact_solref(0.3, 0.002, 0.016, 2.0, 0.002)
    assert (mu, solref, solimp[:2]) == (0.5, [timeconst, dampratio], [d, d])
    # control: another softCFM gives another spring
    assert contact_pair({**props, "softCFM": 0.02}, 2.0, 0.016, 0.002)[1] != solref


def test_motor_numeric_carries_pid_and_position_limits_only_when_they_differ() -> None:
    motor = {"maxVelocity": 3.0, "controlPID": (20.0, 0.5, 0.1), "acceleration": 7.0}
    assert motor_numeric(motor) == [3.0, 20.0, 0.5, 0.1, 7.0]
    assert motor_numeric({**motor, "minPosition": -1.0, "maxPosition": 2.0}) == [3.0, 20.0, 0.5, 0.1, 7.0, -1.0, 2.0]
    assert motor_numeric({**motor, "minPosition": 1.0, "maxPosition": 1.0}) == [3.0, 20.0, 0.5, 0.1, 7.0]
    assert motor_numeric({}) == [10.0, 10.0, 0.0, 0.0, -1.0]  # Webots' defaults


def test_flu_camera_looks_along_the_device_x_axis() -> None:
    device = axis_angle_matrix((0.0, 0.0, 1.0, 0.7))
    cam = camera_rotation(device, old_cameras=False)
    np.testing.assert_allclose(-cam[:, 2], device[:, 0], atol=1e-12)  # MuJoCo looks along -z
    np.testing.assert_allclose(cam[:, 1], device[:, 2], atol=1e-12)  # up is the device's +z
    # control: NUE-era cameras already look along -z
    assert camera_rotation(device, old_cameras=True) is device


def test_rangefinder_site_z_is_the_device_x() -> None:
    device = axis_angle_matrix((1.0, 2.0, 3.0, 0.4))
    np.testing.assert_allclose(rangefinder_rotation(device)[:, 2], device[:, 0], atol=1e-12)


def test_hinge2_second_axis_turns_with_the_first_hinge() -> None:
    np.testing.assert_allclose(hinge2_second_axis((1.0, 0.0, 0.0), math.pi / 2, (0.0, 0.0, 1.0)), [0, -1, 0],
                               atol=1e-12)
    np.testing.assert_allclose(hinge2_second_axis((1.0, 0.0, 0.0), 0.0, (0.0, 0.0, 1.0)), [0, 0, 1])


def _joint() -> mujoco.MjsJoint:
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b", mass=1.0, inertia=[1, 1, 1])
    return body.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE)


def test_joint_dynamics_damping_spring_at_zero_position_and_friction() -> None:
    j = _joint()
    params = {"dampingConstant": 0.3, "springConstant": 4.0, "staticFriction": 0.2}
    assert apply_joint_dynamics(j, params) is False
    assert np.ravel(j.damping)[0] == pytest.approx(0.3)
    assert np.ravel(j.stiffness)[0] == pytest.approx(4.0)
    assert (j.springref, j.frictionloss) == (0.0, 0.2)  # the spring rests at the zero position (§4.5)
    # control: a suspension is reported
    k = _joint()
    assert apply_joint_dynamics(k, {"suspensionSpringConstant": 10.0}) is True


def test_convert_package_has_no_import_cycle() -> None:
    graph = grimp.build_graph("dualtwin")
    modules = sorted(m for m in graph.modules if m.startswith("dualtwin.convert."))
    assert "dualtwin.convert.equivalences" in modules
    cycles = [(a, b) for a in modules for b in modules
              if a < b and graph.chain_exists(a, b) and graph.chain_exists(b, a)]
    assert cycles == []
    # the binding generator reads conversions through a protocol, not by importing them
    assert not graph.chain_exists("dualtwin.convert.bindings", "dualtwin.convert.webots_to_mjcf")
