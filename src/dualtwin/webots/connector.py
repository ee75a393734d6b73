"""Connector: docking connectors that lock two bodies together with a fixed joint, as Webots does.

What Webots documents (Connector reference page) and this module does:

* **Compatibility**: same ``model``; an ``active`` connector docks with a ``passive`` one, a ``symmetric`` one with
  a ``symmetric`` one.
* **In position** (the presence state): the origins are within ``distanceTolerance``; the x axes (the docking
  axes, pointing out of each connector) are opposite within ``axisTolerance``; and, unless
  ``numberOfRotations`` is 0, the z axes differ by a multiple of ``2π/numberOfRotations`` about the docking
  axis within ``rotationTolerance``.
* **Run-time edits**: every field is read when used, so a supervisor's write of a tolerance, ``type``,
  ``model``, ``autoLock``, ``unilateralLock``/``unilateralUnlock``, ``snap`` or a strength acts from the next
  step; a write of ``isLocked`` acts as ``lock()``/``unlock()`` would at the next step (the reference is silent:
  the Connector page calls the field the locking state those calls change).
* ``getPresence()`` reads 1 while the connector is docked to a peer or a compatible peer is in position, else
  0; a ``passive`` connector has no presence sensor and reads -1 (Webots' "not applicable").
* **Lock**: ``lock()`` sets ``isLocked``; at the next physics step, if a compatible peer is in position and
  either ``unilateralLock`` is TRUE or the peer is locked too (a passive peer always agrees), an ODE fixed
  joint is created between the two bodies at their current relative pose. With ``autoLock`` TRUE a locked
  connector keeps trying at every step, so it docks as soon as a peer comes in position; ``isLocked TRUE`` in
  the world file is a lock at load. The two docked bodies stop colliding with each other, as any jointed pair.
* **Unlock**: ``unlock()`` clears ``isLocked``; the joint is destroyed when ``unilateralUnlock`` is TRUE or the
  peer is not locked either.
* **Strength**: after each physics step the joint's feedback force on the connector's body is split into the
  tensile part (along the connector's x axis, pulling the two apart) and the shear part (perpendicular); when
  either exceeds the effective ``tensileStrength``/``shearStrength`` (the sum over the locked connectors of the
  pair, as Webots documents; -1 on a locked side = unbreakable), the joint breaks and both connectors unlock,
  so an autoLock connector does not dock again at once.
  Presence then reads 0: the broken pair is no longer counted as docked.

* **Snap** (``snap TRUE``, the locking side's field): on docking, the body carrying the locking connector (the
  peer's when that one is static) is moved so the connectors' x axes are exactly opposite, the z axes on the
  nearest of the ``numberOfRotations`` docking positions (free when 0) and the origins superimposed; the joint
  then holds that pose, and joints to the rest of the robot pull it along. With ``snap FALSE`` the joint keeps
  the relative pose the bodies had. (Which Solid Webots moves is not documented: moving the whole robot instead
  broke the pair at once in the conformance port of Webots' connector_detach test, so the carrying body alone
  moves.)
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.device_base import Device, DeviceBinding, SampledDevice
from dualtwin.webots.fixed_link import FixedLink, body_of
from dualtwin.webots.physics import Simulation, SolidRec
from dualtwin.webots.physics.edit_stamps import stamps_of

__all__ = ["Connector", "ConnectorState", "install"]


@dataclass(eq=False)
class ConnectorState:
    """One Connector node's docking state in a simulation."""

    solid: SolidRec
    locked: bool
    peer: ConnectorState | None = None
    link: FixedLink | None = None
    owner: bool = False  # the joint's first body is this side's
    pending: bool = False  # lock() was called: try to dock at the next step
    written: int = 0  # the edit stamp of the isLocked field when this state last followed it

    def field(self, name: str, default: Any) -> Any:
        return self.solid.node.fields.get(name, default)

    @property
    def kind(self) -> str:
        return str(self.field("type", "symmetric"))

    def compatible(self, other: ConnectorState) -> bool:
        if other is self or str(self.field("model", "")) != str(other.field("model", "")):
            return False
        kinds = {self.kind, other.kind}
        return kinds == {"active", "passive"} or kinds == {"symmetric"}


def in_position(sim: Simulation, a: ConnectorState, b: ConnectorState) -> bool:
    """Webots' alignment test between two connectors (module docstring), with ``a``'s tolerances."""
    pa, pb = sim.solid_world_pose(a.solid), sim.solid_world_pose(b.solid)
    if m3.norm(m3.sub(pa.t, pb.t)) > float(a.field("distanceTolerance", 0.01)):
        return False
    xa, xb = pa.rotate((1.0, 0.0, 0.0)), pb.rotate((1.0, 0.0, 0.0))
    if math.acos(max(-1.0, min(1.0, -m3.dot(xa, xb)))) > float(a.field("axisTolerance", 0.2)):
        return False
    n = int(a.field("numberOfRotations", 4))
    if n <= 0:
        return True
    za, zb = pa.rotate((0.0, 0.0, 1.0)), pb.rotate((0.0, 0.0, 1.0))
    # signed angle from za to zb about a's docking axis (both projected on the plane normal to it)
    ya = m3.cross(xa, za)
    angle = math.atan2(m3.dot(zb, ya), m3.dot(zb, za))
    sector = 2.0 * math.pi / n
    off = math.fmod(abs(angle), sector)
    return min(off, sector - off) <= float(a.field("rotationTolerance", 0.2))


class Connectors:
    """Per-simulation hook: docking, autoLock and strength checks of every Connector (see module docstring)."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.states = [
            ConnectorState(solid, bool(solid.node.fields.get("isLocked", False)))
            for solid in sim.solids
            if solid.node.type_name == "Connector"
        ]
        for state in self.states:
            state.pending = state.locked
        self.stamps = stamps_of(sim)
        sim.pre_step_hooks.append(self.before_step)
        sim.step_hooks.append(self.after_step)
        sim.reset_hooks.append(self.reset)

    def state_of(self, solid: SolidRec) -> ConnectorState | None:
        return next((s for s in self.states if s.solid is solid), None)

    def peer_in_position(self, state: ConnectorState) -> ConnectorState | None:
        for other in self.states:
            if other.peer is None and state.compatible(other) and in_position(self.sim, state, other):
                return other
        return None

    def presence(self, state: ConnectorState) -> int:
        if state.kind == "passive":
            return -1
        if state.peer is not None:
            return 1
        return 1 if self.peer_in_position(state) is not None else 0

    # -- docking

    def _agrees(self, state: ConnectorState, peer: ConnectorState) -> bool:
        return bool(state.field("unilateralLock", True)) or peer.locked or peer.kind == "passive"

    def _snap(self, state: ConnectorState, peer: ConnectorState) -> None:
        """Move the body carrying ``state`` so its connector exactly faces ``peer``'s: x axes opposite, z axes
        on the nearest of the ``numberOfRotations`` docking positions, origins superimposed. When that side is
        static, the peer's body moves instead; joints to other bodies pull the rest along in the next steps."""
        body = body_of(state.solid)
        if body is None:
            state, peer = peer, state
            body = body_of(state.solid)
            if body is None:
                return
        sim = self.sim
        current, target = sim.solid_world_pose(state.solid), sim.solid_world_pose(peer.solid)
        facing = target * m3.Pose(m3.rot_axis_angle((0.0, 0.0, 1.0, math.pi)))  # x opposite, z kept
        n = int(state.field("numberOfRotations", 4))
        if n > 0:
            turns = [m3.Pose(m3.rot_axis_angle((1.0, 0.0, 0.0, 2.0 * math.pi * k / n))) for k in range(n)]
            rotation = min(((facing * t).R for t in turns), key=lambda r: _angle_between(r, current.R))
        else:  # free about the docking axis: the smallest rotation taking x onto -x_peer
            x_now, x_want = current.rotate((1.0, 0.0, 0.0)), facing.rotate((1.0, 0.0, 0.0))
            rotation = m3.mat_mul(_rotation_between(x_now, x_want), current.R)
        moved = m3.Pose(rotation, target.t) * current.inverse() * body.pose()
        lib = sim._lib
        lib.dBodySetPosition(body.ptr, *moved.apply(body.com))
        r = moved.R
        lib.dBodySetRotation(body.ptr, (ctypes.c_double * 12)(r[0], r[1], r[2], 0.0, r[3], r[4], r[5], 0.0, r[6], r[7], r[8], 0.0))

    def attach(self, state: ConnectorState, peer: ConnectorState) -> None:
        if bool(state.field("snap", True)):
            self._snap(state, peer)
        b1, b2 = body_of(state.solid), body_of(peer.solid)
        if b1 is None and b2 is None or b1 is b2:
            return
        if b1 is None:  # ODE wants the dynamic body first when the other side is the static world
            state, peer, b1, b2 = peer, state, b2, b1
        assert b1 is not None
        link = FixedLink(self.sim, b1, b2)
        state.peer, peer.peer = peer, state
        state.link = peer.link = link
        state.owner, peer.owner = True, False

    def detach(self, state: ConnectorState) -> None:
        peer = state.peer
        if peer is None or state.link is None:
            return
        state.link.destroy()
        for s in (state, peer):
            s.peer = None
            s.link = None
            s.owner = False

    def lock(self, state: ConnectorState) -> None:
        state.locked = True
        state.pending = True
        state.solid.node.fields["isLocked"] = True

    def unlock(self, state: ConnectorState) -> None:
        state.locked = False
        state.pending = False
        state.solid.node.fields["isLocked"] = False
        peer = state.peer
        if peer is not None and (bool(state.field("unilateralUnlock", True)) or not peer.locked):
            self.detach(state)

    # -- hooks

    def _follow_written_lock(self, state: ConnectorState) -> None:
        """A supervisor wrote ``isLocked``, the field that is the connector's locking state (the Connector page:
        the state lock() and unlock() change): a value other than the state acts as that call would."""
        stamp = self.stamps.get((id(state.solid.node), "isLocked"), 0)
        if stamp == state.written:
            return
        state.written = stamp
        wanted = bool(state.field("isLocked", False))
        if wanted != state.locked:
            (self.lock if wanted else self.unlock)(state)

    def before_step(self, _dt: float) -> None:
        for state in self.states:
            self._follow_written_lock(state)
            if not state.locked or state.peer is not None:
                continue
            if not (state.pending or bool(state.field("autoLock", False))):
                continue
            state.pending = False
            peer = self.peer_in_position(state)
            if peer is not None and self._agrees(state, peer):
                self.attach(state, peer)

    def after_step(self) -> None:
        for state in self.states:
            peer, link = state.peer, state.link
            if not state.owner or peer is None or link is None:
                continue
            axis = self.sim.solid_world_pose(state.solid).rotate((1.0, 0.0, 0.0))
            if link.breaks(axis, _strength(state, peer, "tensileStrength"), _strength(state, peer, "shearStrength")):
                self.detach(state)
                for s in (state, peer):
                    s.locked = False
                    s.pending = False
                    s.solid.node.fields["isLocked"] = False

    def reset(self) -> None:
        for state in self.states:
            if state.peer is not None:
                self.detach(state)
        for state in self.states:
            state.locked = bool(state.solid.node.fields.get("isLocked", False))
            state.pending = state.locked


def _angle_between(a: m3.Mat3, b: m3.Mat3) -> float:
    return m3.axis_angle_from_mat(m3.mat_mul(a, m3.mat_t(b)))[3]


def _rotation_between(u: m3.Vec3, v: m3.Vec3) -> m3.Mat3:
    """The smallest rotation taking unit vector ``u`` onto ``v``."""
    axis = m3.cross(u, v)
    sin_a, cos_a = m3.norm(axis), max(-1.0, min(1.0, m3.dot(u, v)))
    if sin_a < 1e-12:
        if cos_a > 0:
            return m3.IDENTITY
        other = (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0)
        axis = m3.cross(u, other)
    return m3.rot_axis_angle((*m3.normalized(axis), math.atan2(sin_a, cos_a)))


def _strength(state: ConnectorState, peer: ConnectorState, name: str) -> float:
    """Webots' effective strength of a docked pair: the sum over the locked sides (both locked: both fields
    add up); -1 on a locked side makes the link unbreakable."""
    sides = [s for s in (state, peer) if s.locked] or [state]
    values = [float(s.field(name, -1.0)) for s in sides]
    return -1.0 if any(v < 0.0 for v in values) else sum(values)


def install(sim: Simulation) -> Connectors:
    """The simulation's connector hook (created once)."""
    hook = sim.extensions.get("connectors")
    if hook is None:
        hook = sim.extensions["connectors"] = Connectors(sim)
    return hook  # type: ignore[no-any-return]


class _Presence(SampledDevice):
    """The presence sensor of one connector, sampled like every Webots sensor."""

    def __init__(self, binding: DeviceBinding, hook: Connectors, state: ConnectorState) -> None:
        self._hook = hook
        self._state = state
        super().__init__(binding)
        self.value = -1

    def _invalidate(self) -> None:
        self.value = -1

    def _read(self) -> None:
        self.value = self._hook.presence(self._state)


class Connector(Device):
    """Webots ``Connector`` (module docstring)."""

    # built on first use, so the constructor stays the one every Device has
    def _docking(self) -> tuple[Connectors, ConnectorState, _Presence]:
        cached = self.__dict__.get("_docking_state")
        if cached is None:
            hook = install(self._robot._sim)
            state = hook.state_of(self._record.solid)
            assert state is not None
            cached = self.__dict__["_docking_state"] = (hook, state, _Presence(self._binding(), hook, state))
        return cached  # type: ignore[no-any-return]

    def enablePresence(self, sampling_period: Any) -> None:
        self._docking()[2].enable(sampling_period)

    def disablePresence(self) -> None:
        self._docking()[2].disable()

    def getPresence(self) -> int:
        presence = self._docking()[2]
        presence._check_enabled("wb_connector_get_presence", "wb_connector_enable_presence")
        return int(presence.value)

    def getPresenceSamplingPeriod(self) -> int:
        return self._docking()[2].getSamplingPeriod()

    def isLocked(self) -> bool:
        return self._docking()[1].locked

    def lock(self) -> None:
        hook, state, _ = self._docking()
        hook.lock(state)

    def unlock(self) -> None:
        hook, state, _ = self._docking()
        hook.unlock(state)

    locked = property(isLocked)
    presence = property(getPresence)
    presence_sampling_period = property(getPresenceSamplingPeriod)
