"""TouchSensor: Webots' bumper, force and force-3d, from contacts and from the sensor's fixed joint.

Bumper
    Webots sets a flag in its near callback whenever one of the sensor's geoms touches another Solid's geom
    (``dCollide`` finds at least one point), in any physics step; the flag is read and cleared at each sample,
    so the reading is 1.0 if anything touched since the previous sample, else 0.0 (the lookup table is ignored).
    The same pair rules apply as for contacts, except that static-static pairs are tested too: another robot's
    parts and the environment count; the sensor's own robot counts only with ``selfCollision``. Here a step hook
    runs ``dCollide`` for the enabled bumpers' geoms after each step's collision pass (the state that pass saw).
    It works without Physics.

Force and force-3d
    With Physics, the sensor is *not* merged into its parent: it has its own body, attached to the parent's
    (or to the static environment) by a fixed joint whose ``dJointFeedback`` gives the force the joint applies
    to the parent, ``f1`` (world frame). A sensor that is a joint's endPoint is held by that joint instead (no
    fixed joint; the reference is silent on this case), whose feedback is read the same way. force: the push along the sensor's −x axis (onto the robot),
    ``input = max(0, −x̂·f1)``; force-3d: ``R_sensorᵀ·f1``, each component through the table separately (with the
    default table, negative components read 0, as in Webots). Then the lookup table (empty: raw newtons) and
    the resolution. The joint also carries the sensor's own weight, as in Webots. Without Physics the force
    types read ``lookup(0)`` (Webots warns likewise).

Values are NaN until the first sample (controller side); ``getValue`` of a force-3d sensor and ``getValues`` of
the others print an error and return NaN.
"""

from __future__ import annotations

import ctypes
import math
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.api_args import error, warn
from dualtwin.webots.device_base import SolidSensor
from dualtwin.webots.lut import Table, discretize, lookup, table_from_field
from dualtwin.webots.physics import GeomRec, JointRec, Simulation, SolidRec
from dualtwin.webots.step_hints import step_value

__all__ = ["TouchSensor", "bumper_touches"]

_TYPES = {"bumper": 0, "force": 1, "force-3d": 2}


def _sensor_solids(solid: SolidRec) -> list[SolidRec]:
    """The TouchSensor Solid and the Solids merged into it: its subtree, less what hangs from a joint. A joint's
    endPoint is another Solid with its own body, and only "one of the sensor's geoms" touching something sets
    the flag (webots-devices.md §2.3), so a wheel or finger jointed below a bumper does not make it touch."""
    out, stack = [], [solid]
    while stack:
        s = stack.pop()
        out.append(s)
        stack.extend(c for c in s.children if c.joint is None)
    return out


def bumper_touches(sim: Simulation, solid: SolidRec) -> bool:
    """Whether the TouchSensor Solid's geoms touch another Solid's geoms now (Webots' bumper pair rules)."""
    mine = [g for s in _sensor_solids(solid) for g in s.geoms]
    if not mine:
        return False
    # what hangs below the sensor is never the "other" Solid either: whether its joint excludes the pair, as it
    # excludes contacts, is not settled (webots-devices.md §2.3 is silent)
    own = {id(s) for s in solid.subtree()}
    robot = solid.robot
    others: list[GeomRec] = [
        g
        for g in sim.geoms.values()
        if id(g.solid) not in own and (robot is None or robot.self_collision or g.solid.robot is not robot)
    ]
    lib = ode.load()
    buf = (ode.dContactGeom * 1)()
    size = ctypes.sizeof(ode.dContactGeom)
    base = ctypes.addressof(buf)
    order = sim.space_order()  # the collision pass's argument order (some colliders are order-dependent)
    for g in mine:
        for h in others:
            a, b = (g.ptr, h.ptr) if order.get(g.ptr, 0) <= order.get(h.ptr, 0) else (h.ptr, g.ptr)
            if lib.dCollide(a, b, 1, base, size) > 0:
                return True
    return False


class _Bumpers:
    """Per-simulation step hook setting the flag of every enabled bumper touched during the step."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.active: dict[int, TouchSensor] = {}
        sim.step_hooks.append(self.after_step)
        sim.reset_hooks.append(self.reset)

    def reset(self) -> None:
        for sensor in self.active.values():
            sensor._touched = False

    def after_step(self) -> None:
        for sensor in self.active.values():
            if not sensor._touched and bumper_touches(self.sim, sensor._record.solid):
                sensor._touched = True


def _bumpers(sim: Simulation) -> _Bumpers:
    hook = sim.extensions.get("bumpers")
    if hook is None:
        hook = sim.extensions["bumpers"] = _Bumpers(sim)
    return hook


class TouchSensor(SolidSensor):
    """Webots ``TouchSensor`` (see the module docstring)."""

    BUMPER = 0
    FORCE = 1
    FORCE3D = 2

    def _kind(self) -> int:
        kind = getattr(self, "_kind_cache", None)
        if kind is None:
            raw = str(self._record.node.fields.get("type", "bumper"))
            kind = _TYPES.get(raw)
            if kind is None:
                warn(f"TouchSensor '{self._name}': unknown type '{raw}', using 'bumper'")
                kind = self.BUMPER
            self._kind_cache = kind
            self._feedback: ode.dJointFeedback | None = None
            self._holder: JointRec | None = None
            self._touched = False
            if kind != self.BUMPER:
                self._attach_feedback()
        return kind

    def _attach_feedback(self) -> None:
        """Watch the joint that holds the sensor's body to its parent: its fixed joint, or the joint whose
        endPoint it is (a Solid with Physics there is never merged, and has no fixed joint)."""
        solid = self._record.solid
        body = solid.body
        if body is None or body.root is not solid:
            warn(f"TouchSensor '{self._name}': a force sensor needs Physics; it reads lookup(0)")
            return
        lib = ode.load()
        if body.fixed_joint:
            self._feedback = ode.dJointFeedback()
            lib.dJointSetFeedback(body.fixed_joint, ctypes.byref(self._feedback))
            return
        holder = next((j for j in body.joints if j.child is solid and j.ptr), None)
        if holder is None:  # (a body nothing holds: no force reaches a parent)
            return
        self._holder = holder
        # one feedback buffer per ODE joint: a motor's force feedback (or the battery) may have set it, or set its
        # own later; the reading goes through whichever the joint has (_force_on_parent)
        if not lib.dJointGetFeedback(holder.ptr):
            self._feedback = ode.dJointFeedback()
            lib.dJointSetFeedback(holder.ptr, ctypes.byref(self._feedback))

    def _table(self) -> Table:
        # its lookupTable and resolution are read again after a supervisor's edit, from the next sample on (the
        # type, which decides the ODE feedback set up at load, is not)
        return self._configured("_table_cache",
                                lambda: table_from_field(self._fields().get("lookupTable", [])))

    def _resolution(self) -> float:
        return float(self._record.node.fields.get("resolution", -1.0))

    def enable(self, samplingPeriod: Any) -> None:
        kind = self._kind()
        super().enable(samplingPeriod)
        if kind == self.BUMPER:
            hooks = _bumpers(self._robot._sim)
            if self._period > 0:
                self._touched = False
                hooks.active[id(self._owner)] = self._owner
            else:
                hooks.active.pop(id(self._owner), None)

    def disable(self) -> None:
        super().disable()
        hooks = self._robot._sim.extensions.get("bumpers")
        if hooks is not None:
            hooks.active.pop(id(self._owner), None)

    def _invalidate(self) -> None:
        self._values = [math.nan] * 3
        self._value = math.nan

    def _force_on_parent(self) -> m3.Vec3:
        holder = self._holder
        if holder is not None:
            address = ode.load().dJointGetFeedback(holder.ptr) if holder.ptr else None
            if not address:
                return (0.0, 0.0, 0.0)
            fb = ode.dJointFeedback.from_address(address)
            sensor_first = holder.parent_body is None
        else:
            if self._feedback is None:
                return (0.0, 0.0, 0.0)
            fb = self._feedback
            body = self._record.solid.body
            sensor_first = body is not None and body.fixed_to is None
        f = (fb.f1[0], fb.f1[1], fb.f1[2])
        # held by the static environment, ODE makes the sensor body the joint's first body: f1 is then the force
        # on the sensor, and the force on the "parent" (the environment) is its opposite
        return m3.scale(f, -1.0) if sensor_first else f

    def _read(self) -> None:
        kind = self._kind()
        sim = self._robot._sim
        if kind == self.BUMPER:
            self._value = 1.0 if self._touched else 0.0
            self._touched = False
            return
        R = self._pose().R
        f1 = self._force_on_parent()
        table, resolution = self._table(), self._resolution()  # (once a sample, for the three axes too)
        if kind == self.FORCE:
            p = m3.dot(m3.mat_vec(R, (1.0, 0.0, 0.0)), f1)
            self._value = discretize(lookup(table, -p if p < 0 else 0.0, sim.rng), resolution)
        else:
            local = m3.mat_t_vec(R, f1)
            self._values = [discretize(lookup(table, v, sim.rng), resolution) for v in local]

    @step_value
    def getValue(self) -> float:
        self._check_enabled("wb_touch_sensor_get_value", "wb_touch_sensor_enable")
        if self._kind() == self.FORCE3D:
            error("TouchSensor.getValue() cannot be used with a 'force-3d' sensor: use getValues()")
            return math.nan
        return self._value

    @step_value
    def getValues(self) -> list[float]:
        self._check_enabled("wb_touch_sensor_get_values", "wb_touch_sensor_enable")
        if self._kind() != self.FORCE3D:
            warn("TouchSensor.getValues() can only be used with a 'force-3d' sensor: use getValue()")
            return [math.nan] * 3
        return list(self._values)

    def getLookupTable(self) -> list[float]:
        self._kind()
        return [v for row in self._table() for v in row]

    def getType(self) -> int:
        return self._kind()

    value = property(getValue)
    values = property(getValues)
    lookup_table = property(getLookupTable)
    type = property(getType)
