"""Build an ODE scene from a parsed Webots world and step it as Webots R2023b does.

Specification: ``docs/reference/webots-on-ode.md`` (cited as §N below). Public entry point:
:class:`Simulation` (``Simulation(world)``, ``step()``, ``reset()``, ``reset_physics()``).

Layout: this module is the façade (construction, build order, reset, close). The work is done by layers, one
module each, every layer calling only the layers below it: ``records`` (the dataclasses), ``core`` (shared
state, scene-graph poses), ``build`` (traversal, bodies with the mass rules of
:mod:`dualtwin.webots.mass_rules`, geoms, devices), ``joints``, ``collision`` (the contact pass),
``world_edits`` (run-time WorldInfo edits: gravity, ERP/CFM, sleep, basicTimeStep), ``edits`` (supervisor
requests, field edits, sensor readings), ``axis_edits`` (run-time joint axis and anchor edits), ``stepping`` and
``scene_changes`` (nodes a supervisor imports or removes at run time), ``physics_changes``, ``frame_edits`` and
``velocity_edits`` (a Solid's velocity fields written at run time).

What follows Webots
    One ``dWorldStep`` per ``basicTimeStep``, ENU gravity, world ERP/CFM, damping conversion, max angular
    speed, time-based auto-disable (§1); contacts from the collision pass after step *k* consumed by
    step *k+1* with per-body double-buffered joint groups, the near-callback filters of §2.3, first
    matching ContactProperties, Approx1 pyramid friction with soft ERP/CFM and bounce (§2); mass modes,
    CoM-centred bodies, Solid merging and the static basis (§3); Hinge/Slider/Hinge2/Ball joints with
    Webots' ODE sign conventions, stops, implicit springs and static friction (§4); motor control with
    the exact PID/velocity/acceleration/torque logic and the initial hold (§5).

What differs (and why)
    * Slider springs: upstream ODE's LMotor has no stops (the position-stop LMotor is a Webots fork
      feature), so the spring row is emulated with the LMotor *motor* row: velocity target
      ``∓ERP·x/h`` with CFM ``1/(hK+B)`` and unbounded force, which is algebraically the same implicit
      LCP row as a stop row with that ERP/CFM (Appendix A).
    * Asymmetric friction (2–4 ``coulombFriction`` values) sets fdir1/mu2 per contact from both geometries'
      friction directions (which face gives which direction is our reading of Webots' texture mapping);
      asymmetric ``forceDependentSlip`` uses its first value; fluids push immersed Solids by buoyancy only
      (``immersion``: no drag or viscous resistance). Ray devices, touch sensors and radios live in their
      own modules (``ranging``, ``touch``, ``radio``) and use the ``extensions``/``step_hooks`` slots.
    * Hinge suspension (fork-only ODE API, Appendix A.2) is not modelled; BallJoint springs/dampers are the
      stop rows of a second Euler AMotor; BallJoint
      positions are read from the bodies' rotations (ODE updates its Euler angles only inside a step); upstream
      ODE never limits the second Hinge2 axis, so a one-axis stop AMotor carries its stops. A Brake adds its damping constant to
      the axis' implicit damper; coupled motors ("name::suffix") are relayed by the controller API and their
      limits harmonised at load.
    * ODE 0.16's ``dJointAddHingeTorque`` negates the torque of reversed hinges (static parent); the
      torque is pre-negated so a positive ``setTorque`` increases the position for every hinge, as
      Webots documents (whether its 0.13.1 fork negates too is UNVERIFIED).
    * All geoms go directly into one top-level simple space (no per-body child spaces); geoms of one body
      never collide anyway, so only the order in which ODE reports pairs may differ.
    * ODE's category/collide bits pre-filter pairs that §2.3 rules 4/5 discard anyway (static–static,
      same robot without selfCollision) so the Python near-callback only sees useful pairs.
    * The Debian ``libode8`` keeps ODE's assertions: a non-finite state inside ``dWorldStep`` aborts the
      process. :class:`SimulationUnstable` is therefore raised on non-finite *or diverging* state
      (|x| > 1e9 m, |v| > 1e8 m/s) right after the step, before the collision pass would see it; and the
      step itself runs through ``webots/native/ode_guard.c`` where a C compiler is at hand (:func:`.ode.guarded_step`),
      so that an assertion inside it (numbers that overflow within one step) raises
      :class:`SimulationUnstable` instead of ending the process. Such a world is half stepped: it is never
      stepped or reset again (load it again).

UNVERIFIED choices (spec gaps, most plausible behaviour picked)
    * "Kinematic solid touches a disabled body" (§2.3 rule 9) covers every body-less geom.
    * Solids named "left wheel"/"right wheel" that are not merged are tied to their parent body with a
      fixed joint; a physics Solid under a physics-less Solid that itself has a physics ancestor is tied
      to that nearest body with a fixed joint (Webots calls this configuration undefined).
    * ``maxContactJoints`` keeps the deepest points in their original collider order.
    * Hinge2 second axis: position2 = +angle2 + offset2 (spec) with motor ``dParamVel2 = -u`` and torque
      ``(0, -τ)``, the signs for which a positive command turns the endPoint about +axis2 (checked);
      ``jointParameters2 NULL`` uses axis ``0 0 1``.
    * Joint motor commands and supervisor teleports wake the affected bodies (``dBodyEnable``).
    * A Hinge2Joint without a parent body (no ODE joint, §4.4) is kinematic even when its endPoint has a body:
      that body is placed on the joint's pose, at rest, after every physics step.
    * Kinematic joints (endPoint without Physics) ramp their speed by the acceleration (or the available
      torque, §5.3); in position control the speed is a magnitude that ramps again from rest after a stop,
      and a new target in the other direction keeps the speed reached (the reversal is not documented).
    * Damping of merged bodies is volume-weighted; solids without boundingObject get weight 0 unless all
      weights are 0 (then a plain average).
    * Sensors sample at the end of a controller step once their sampling period has elapsed; the
      Accelerometer differentiates the CoM velocity of its body over the last basic step; Gyro and
      ``Node.getVelocity`` of a body-less Solid use its nearest body's motion (kinematic joint motion
      is not added).
"""

from __future__ import annotations

import random
import threading
import time as _time
from typing import Any

from dualtwin.errors import SimulationUnstable
from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.nodes import Node, World
from dualtwin.webots.physics import immersion
from dualtwin.webots.physics.motor_edits import execute_motor_edits
from dualtwin.webots.physics.records import (
    ATTACHMENT_TYPES,
    JOINT_TYPES,
    MOTOR_TYPES,
    SOLID_TYPES,
    AttachmentRec,
    BodyRec,
    BrakeRec,
    DeviceRec,
    GeomRec,
    JointRec,
    MotorRec,
    PositionSensorRec,
    RobotRec,
    SolidRec,
    WorldBuildError,
    damping_per_step,
)
from dualtwin.webots.physics.records import field_or as _f
from dualtwin.webots.physics.velocity_edits import SolidVelocityEdits
from dualtwin.webots.physics.world_edits import gravity_vector, sleep_settings

__all__ = [
    "Simulation",
    "SimulationUnstable",
    "WorldBuildError",
    "SolidRec",
    "BodyRec",
    "BrakeRec",
    "JointRec",
    "MotorRec",
    "PositionSensorRec",
    "DeviceRec",
    "RobotRec",
    "AttachmentRec",
    "GeomRec",
    "ATTACHMENT_TYPES",
    "JOINT_TYPES",
    "MOTOR_TYPES",
    "SOLID_TYPES",
]


class Simulation(SolidVelocityEdits):
    """A Webots world simulated on ODE with Webots' stepping semantics.

    Args:
        world: a parsed world (every base node with all its fields filled).
        seed: overrides ``WorldInfo.randomSeed`` for the sensor-noise RNG.

    Example:
        >>> sim = Simulation(load_world("worlds/cartpole.wbt"))  # doctest: +SKIP
        >>> sim.step(); sim.time                                  # doctest: +SKIP
        0.032
    """

    def __init__(self, world: World, *, seed: int | None = None) -> None:
        self.world = world
        self._lib = lib = ode.load()
        ode.ensure_thread()
        self._thread = threading.get_ident()
        # cached ctypes function objects for the per-step paths; the world step returns where ODE would abort
        # the process on an internal error (webots/native/ode_guard.c), else it is ODE's own
        self._step_fn = ode.guarded_step() or lib.dWorldStep
        self._broken: str | None = None  # what ODE said when it stopped inside a step: never stepped again
        self._is_enabled = lib.dBodyIsEnabled
        self._empty_group = lib.dJointGroupEmpty
        self._hinge_angle = lib.dJointGetHingeAngle
        self._hinge_rate = lib.dJointGetHingeAngleRate
        self._slider_pos = lib.dJointGetSliderPosition
        self._warnings = []
        self.robots = []
        self.solids = []
        self.bodies = []
        self.joints = []
        self.geoms = {}
        self.motors = []
        self.devices = []
        self.attachments = []
        self._loops = []  # joints whose endPoint is a SolidReference
        self._solid_by_node = {}
        self._joint_by_node = {}
        self._frame_factors = {}
        self._pending = []
        self._unexecuted = {}
        self._edited = {}
        self._unstable = False
        self._closed = False
        self.step_count = 0
        self._time_base = 0.0
        self._steps_base = 0
        self._seed_override = seed
        self._accel_prev = {}
        self._accel_cur = {}
        # device modules (rays, touch, radio, ...) keep their per-simulation state here, under their own key,
        # and register callables run after each step's collision pass (post-step state, contacts of the step)
        self.extensions = {}
        self.step_hooks = []
        self.sample_hooks = []  # run after every step hook: controllers' sensors sampling (device_base)
        self.pre_step_hooks = []
        self.reset_hooks = []  # device state that simulationReset restores
        self._read_world_info()
        self._snapshot = self._snapshot_fields()
        self._build()
        immersion.install(self)  # buoyancy: a pre-step hook, only where a Solid is immersed in a Fluid

    # ------------------------------------------------------------------ world info

    def _read_world_info(self) -> None:
        info = self.world.world_info()
        step_ms = float(_f(info, "basicTimeStep", 32.0))
        if step_ms <= 0:
            step_ms = 32.0  # §1.1: reset to 32 if ≤ 0
        self.basic_time_step = step_ms
        self.dt = step_ms * 0.001
        g = float(_f(info, "gravity", 9.81))
        # one reading for gravity and every device (the Compass's): ENU, NUE or EUN in any case, else ENU
        written = str(_f(info, "coordinateSystem", "ENU"))
        cs = written.upper()
        if cs not in ("ENU", "NUE", "EUN"):
            self.warn_once(f'WorldInfo: coordinateSystem "{written}" is not "ENU", "NUE" or "EUN": the world is read as '
                           "ENU (gravity along -z, north +y)")
        self.coordinate_system = cs = cs if cs in ("ENU", "NUE", "EUN") else "ENU"
        gps_system = str(_f(info, "gpsCoordinateSystem", "local"))
        if gps_system not in ("local", "WGS84"):
            self.warn_once(f'WorldInfo: gpsCoordinateSystem "{gps_system}" is not "local" or "WGS84": GPS devices read '
                           "local coordinates")
        self.gravity = gravity_vector(g, cs)  # along the system's down
        erp = float(_f(info, "ERP", 0.2))
        cfm = float(_f(info, "CFM", 0.00001))
        self.erp = erp if 0.0 <= erp <= 1.0 else 0.2
        self.cfm = cfm if cfm > 0.0 else 0.00001
        self.disable_time, self.disable_lin, self.disable_ang = sleep_settings(info)
        damping = _f(info, "defaultDamping", None)
        self.world_damping = (
            (
                damping_per_step(float(_f(damping, "linear", 0.2)), self.dt),
                damping_per_step(float(_f(damping, "angular", 0.2)), self.dt),
            )
            if isinstance(damping, Node)
            else (0.0, 0.0)
        )
        plugin = str(_f(info, "physics", "<none>"))
        if plugin not in ("", "<none>"):
            self.warn(f"WorldInfo.physics names the physics plugin '{plugin}': physics plugins are not run here, "
                      "the world is simulated without it")
        self.random_seed = int(_f(info, "randomSeed", 0))
        self.contact_properties = [
            cp for cp in (_f(info, "contactProperties", []) or []) if isinstance(cp, Node)
        ]

    def _rng_seed(self) -> int:
        if self._seed_override is not None:
            return self._seed_override
        return self.random_seed if self.random_seed >= 0 else int(_time.time())

    # ------------------------------------------------------------------ snapshot / restore of fields

    def _snapshot_fields(self) -> list[tuple[Node, dict[str, Any], dict[str, Any] | None]]:
        def copied(values: dict[str, Any]) -> dict[str, Any]:
            return {k: (list(v) if isinstance(v, list) else v) for k, v in values.items()}

        snap = []
        for top in self.world.nodes:
            for node in top.walk():
                interface = None if node.proto_fields is None else copied(node.proto_fields)
                snap.append((node, copied(node.fields), interface))
        return snap

    def load_fields(self, node: Node) -> dict[str, Any] | None:
        """The values ``node``'s fields had at load (what ``simulationReset`` restores), None for a node added since."""
        return next((dict(values) for n, values, _ in self._snapshot if n is node), None)

    def _restore_fields(self) -> None:
        for node, values, interface in self._snapshot:
            node.fields.clear()
            node.fields.update({k: (list(v) if isinstance(v, list) else v) for k, v in values.items()})
            if interface is not None and node.proto_fields is not None:
                # a PROTO instance's fields are restored with the nodes they feed (Webots resets every field)
                node.proto_fields.clear()
                node.proto_fields.update({k: (list(v) if isinstance(v, list) else v) for k, v in interface.items()})

    # ------------------------------------------------------------------ build

    def _build(self) -> None:
        lib = self._lib
        self._world = lib.dWorldCreate()
        lib.dWorldSetGravity(self._world, *self.gravity)
        lib.dWorldSetERP(self._world, self.erp)
        lib.dWorldSetCFM(self._world, self.cfm)
        # §1.2: damping always active; set before bodies exist since bodies copy world settings.
        lib.dWorldSetLinearDampingThreshold(self._world, 0.0)
        lib.dWorldSetAngularDampingThreshold(self._world, 0.0)
        lib.dWorldSetDamping(self._world, *self.world_damping)
        lib.dWorldSetAutoDisableTime(self._world, max(self.disable_time, 0.0))
        lib.dWorldSetAutoDisableSteps(self._world, 0)
        lib.dRandSetSeed(max(self.random_seed, 0))
        self._space = lib.dSimpleSpaceCreate(None)
        lib.dSpaceSetCleanup(self._space, 0)

        for top in self.world.nodes:
            self._walk_top(top)
        self._assign_bodies()
        for body in self.bodies:
            self._create_body(body)
        self._categories()
        for solid in self.solids:
            self._create_geoms(solid)
        for joint in self.joints:
            self._create_joint(joint)
        for joint, name in self._loops:
            self._close_loop(joint, name)
        self._create_fixed_joints()
        self._collect_devices()
        self._init_contacts()
        self._prepare_step_lists()
        self._rng = random.Random(self._rng_seed())
        for motor in self.motors:
            motor.reset_state()
        self._collide()  # §1.6: one collision pass at load, used by the first step

    # ------------------------------------------------------------------ reset (§6)

    def reset(self) -> None:
        """``simulationReset``: restore the load state exactly (fields, poses, joints, motors, contacts, RNG).

        Raises:
            SimulationUnstable: ODE stopped inside a step of this world (its state is half stepped): load the
                world again."""
        if self._broken is not None:
            raise SimulationUnstable(f"{self._broken}; this world cannot be reset: load it again")
        lib = self._lib
        self._pending.clear()
        self._unexecuted.clear()
        self._restore_fields()
        execute_motor_edits(self)  # the restored fields now, the load configuration then (reset hooks) over them
        self.contact_properties_changed()  # (a supervisor may have imported or removed some)
        for body in self.bodies:
            for g in body.groups:
                lib.dJointGroupEmpty(g)
        self._used = [[], []]
        self._buffer = 0
        for solid in self.solids:
            solid.rel = solid.load_rel
        for body in self.bodies:
            if body.removed:
                continue  # its Solid left the scene at run time; a reset does not bring it back
            self._place_body_at_load(body)
            self._set_auto_disable(body)
        for joint in self.joints:
            joint.positions = list(joint.initial_positions)
            # the load axes and anchor (edited ones are applied to ODE again below, with the load values)
            joint.axis_local[:] = joint.zero_axes[:] = joint.load_axes
            joint.anchor_local = joint.zero_anchor = joint.load_anchor
            if joint.ptr:
                self._anchor_joint(joint)
                for i in range(len(joint.params)):
                    self._set_stops(joint, i)
                if joint.spring and joint.kind == "hinge":
                    stop = m3.normalize_angle(joint.offsets[0])
                    lib.dJointSetAMotorParam(joint.spring, ode.dParamLoStop, stop)
                    lib.dJointSetAMotorParam(joint.spring, ode.dParamHiStop, stop)
                    lib.dJointSetAMotorAngle(joint.spring, 0, 0.0)
                for i, m in enumerate(joint.motors):
                    if m is not None or joint.static_friction[i] > 0:
                        self._set_motor_row(joint, i, 0.0, joint.static_friction[i] if m is None else 0.0)
        for gr in self.geoms.values():
            if gr.body is None:
                self._place_static_geom(gr, self.solid_world_pose(gr.solid))
        for (_, name), node in list(self._edited.items()):
            self._apply_field(node, name)
        self._edited.clear()
        for motor in self.motors:
            motor.reset_state()
            # §5.2: setAcceleration replaced the motor's acceleration field, which a reset restores (§6; the
            # motors' acceleration is among what webots-devices.md §11.3 lists as reset)
            motor.acceleration = motor.load_acceleration
        self._enabled[:] = [not b.removed for b in self.bodies]
        self._accel_prev.clear()
        for index in self._accel_cur:
            b = self.bodies[index]
            self._accel_cur[index] = (b.lvel[0], b.lvel[1], b.lvel[2])
        lib.dRandSetSeed(max(self.random_seed, 0))
        self._rng = random.Random(self._rng_seed())
        self._unstable = False
        self.step_count = 0
        self._time_base = 0.0
        self._steps_base = 0
        for hook in self.reset_hooks:
            hook()
        self.scene_version += 1  # (the tree as at load, without the nodes added since)
        self._collide()

    def close(self) -> None:
        """Destroy the ODE world (idempotent)."""
        if self._closed:
            return
        self._closed = True
        lib = self._lib
        for gr in self.geoms.values():
            self._destroy_geom(gr)
        for body in self.bodies:
            for g in body.groups:
                lib.dJointGroupDestroy(g)
        lib.dSpaceDestroy(self._space)
        if self._broken is None:  # (a world ODE stopped inside a step is left as it is: its memory is lost)
            lib.dWorldDestroy(self._world)

    def __del__(self) -> None:
        try:
            if not self._closed and hasattr(self, "_world"):
                self.close()
        except Exception:
            pass
