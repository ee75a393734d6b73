"""Webots-twin physics throughput: basic steps per second on the bundled CartPole-on-wheels world.

Run: ``python bench/bench_webots_physics.py`` (or ``make bench``). Goal: >= 5,000 steps/s on one core
while the wheels drive and the pole swings (auto-disable never kicks in), both for ``Simulation.step`` and
through the controller API (``Supervisor.step`` with motor commands).

Baseline, measured in the same run: a raw ODE loop (collide, ``dWorldStep``, empty the contact group) over
an equivalent hand-built scene, the same bodies, joints, motors and contact surface written directly
against the ctypes binding, with the minimal Python near-callback any ctypes ODE loop needs.
"""

from __future__ import annotations

import ctypes
import math
import time
from ctypes import byref

from _common import best_of
from dualtwin.robots.binding import BUNDLED
from dualtwin.webots import load_world, ode
from dualtwin.webots.controller import Supervisor
from dualtwin.webots.physics import Simulation

STEPS = 5000
GOAL = 5000.0


def raw_ode_cartpole(steps: int) -> float:
    """Seconds for ``steps`` steps of a hand-built CartPole scene in plain ODE (the baseline)."""
    lib = ode.load()
    world = lib.dWorldCreate()
    lib.dWorldSetGravity(world, 0.0, 0.0, -9.81)
    lib.dWorldSetERP(world, 0.2)
    lib.dWorldSetCFM(world, 1e-5)
    space = lib.dSimpleSpaceCreate(None)
    floor = lib.dCreatePlane(space, 0.0, 0.0, 1.0, 0.0)
    group = lib.dJointGroupCreate(0)

    def body(mass_fn, geom, x: float, y: float, z: float) -> int:  # type: ignore[no-untyped-def]
        b = lib.dBodyCreate(world)
        m = ode.dMass()
        mass_fn(m)
        lib.dBodySetMass(b, byref(m))
        lib.dBodySetPosition(b, x, y, z)
        lib.dGeomSetBody(geom, b)
        return b

    def box_mass(mass: float, sx: float, sy: float, sz: float):  # type: ignore[no-untyped-def]
        def fn(m: ode.dMass) -> None:
            lib.dMassSetBox(byref(m), 1000.0, sx, sy, sz)
            lib.dMassAdjust(byref(m), mass)
        return fn

    chassis = body(box_mass(1.0, 0.4, 0.2, 0.1), lib.dCreateBox(space, 0.4, 0.2, 0.1), 0.0, 0.0, 0.07)
    hinges = []
    for x, y in ((0.15, 0.12), (0.15, -0.12), (-0.15, 0.12), (-0.15, -0.12)):
        geom = lib.dCreateCylinder(space, 0.04, 0.02)

        def wheel_mass(m: ode.dMass) -> None:
            lib.dMassSetCylinder(byref(m), 1000.0, 3, 0.04, 0.02)
            lib.dMassAdjust(byref(m), 0.05)
        wheel = body(wheel_mass, geom, x, y, 0.04)
        lib.dBodySetRotation(wheel, ode.matrix3(((1, 0, 0), (0, 0, -1), (0, 1, 0))))
        hinge = lib.dJointCreateHinge(world, None)
        lib.dJointAttach(hinge, chassis, wheel)
        lib.dJointSetHingeAnchor(hinge, x, y, 0.04)
        lib.dJointSetHingeAxis(hinge, 0.0, 1.0, 0.0)
        hinges.append(hinge)
    pole = body(box_mass(0.2, 0.02, 0.02, 1.0), lib.dCreateBox(space, 0.02, 0.02, 1.0), 0.0, 0.0, 0.62)
    pole_hinge = lib.dJointCreateHinge(world, None)
    lib.dJointAttach(pole_hinge, chassis, pole)
    lib.dJointSetHingeAnchor(pole_hinge, 0.0, 0.0, 0.12)
    lib.dJointSetHingeAxis(pole_hinge, 0.0, 1.0, 0.0)
    lib.dJointSetHingeParam(pole_hinge, ode.dParamLoStop, -1.0)
    lib.dJointSetHingeParam(pole_hinge, ode.dParamHiStop, 1.0)

    surface = ode.dSurfaceParameters()
    surface.mode = ode.dContactApprox1 | ode.dContactSoftERP | ode.dContactSoftCFM | ode.dContactBounce
    surface.mu = surface.mu2 = 1.0
    surface.bounce, surface.bounce_vel, surface.soft_erp, surface.soft_cfm = 0.5, 0.01, 0.2, 0.001
    contacts = (ode.dContact * 10)()
    for c in contacts:
        c.surface = surface
    geom_array = ctypes.addressof(contacts[0].geom)
    contact_stride = ctypes.sizeof(ode.dContact)

    def near(_data: int, o1: int, o2: int) -> None:
        if o1 != floor and o2 != floor:
            return  # one robot, no self-collision
        n = lib.dCollide(o1, o2, 10, geom_array, contact_stride)
        b1, b2 = lib.dGeomGetBody(o1), lib.dGeomGetBody(o2)
        for i in range(n):
            joint = lib.dJointCreateContact(world, group, byref(contacts[i]))
            lib.dJointAttach(joint, b1, b2)

    callback = ode.NearCallback(near)
    start = time.perf_counter()
    for k in range(steps):
        velocity = 20.0 * math.sin(0.01 * (k - k % 50))
        for hinge in hinges:
            lib.dJointSetHingeParam(hinge, ode.dParamFMax, 2.0)
            lib.dJointSetHingeParam(hinge, ode.dParamVel, -velocity)
        lib.dSpaceCollide(space, None, callback)
        lib.dWorldStep(world, 0.008)
        lib.dJointGroupEmpty(group)
    elapsed = time.perf_counter() - start
    lib.dJointGroupDestroy(group)
    lib.dSpaceDestroy(space)
    lib.dWorldDestroy(world)
    return elapsed


def main() -> dict[str, float]:
    world = load_world(BUNDLED / "cartpole" / "cartpole.wbt")
    sim = Simulation(world)
    sup = Supervisor(simulation=sim, robot_node=sim.robots[0].node)
    wheels = [sup.getDevice(f"wheel{i}") for i in range(1, 5)]
    pole = sup.getDevice("pole sensor")
    pole.enable(int(sim.basic_time_step))

    def drive(k: int) -> None:
        for wheel in wheels:
            wheel.setPosition(math.inf)
            wheel.setVelocity(20.0 * math.sin(0.01 * k))

    def raw() -> None:
        sim.reset()
        drive(1)
        for k in range(STEPS):
            if k % 50 == 0:
                drive(k)
            sim.step()

    def api() -> None:
        sim.reset()
        step_ms = sim.basic_time_step
        for k in range(STEPS):
            drive(k)
            sup.step(step_ms)
            pole.getValue()

    baseline = float("inf")
    raw_best = api_best = float("inf")
    for _ in range(3):  # interleaved, so machine load hits baseline and twin alike
        baseline = min(baseline, raw_ode_cartpole(STEPS))
        raw_best = min(raw_best, best_of(raw, 1))
        api_best = min(api_best, best_of(api, 1))
    ode_rate, raw_rate, api_rate = STEPS / baseline, STEPS / raw_best, STEPS / api_best
    print("== Webots twin physics (bundled cartpole.wbt, driving, one core) ==")
    print(f"  raw ODE loop, hand-built scene : {ode_rate:9.0f} steps/s (baseline)")
    print(f"  Simulation.step                : {raw_rate:9.0f} steps/s  {raw_rate / ode_rate:5.2f}x baseline"
          f"  (goal >= {GOAL:.0f})")
    print(f"  Supervisor.step + motors       : {api_rate:9.0f} steps/s  {api_rate / ode_rate:5.2f}x baseline"
          f"  (goal >= {GOAL:.0f})")
    sim.close()
    return {"ode_steps_per_s": ode_rate, "raw_steps_per_s": raw_rate, "api_steps_per_s": api_rate}


if __name__ == "__main__":
    main()
