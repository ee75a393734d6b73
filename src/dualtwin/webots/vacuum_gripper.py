"""VacuumGripper (Webots R2023b): a suction cup that holds the Solid it touches while it is on.

What Webots documents and this module does:

* the gripper's own ``boundingObject`` senses contacts; while it is on and holds nothing, the first dynamic body
  touching it with at least ``contactPoints`` contact points (of one collision pass) is grasped: an ODE fixed
  joint ties that body to the gripper's body (or to the static world when the gripper has none) at their
  current relative pose, and the two stop colliding, as any jointed pair;
* ``turnOff()`` releases it; ``isOn`` in the world file turns it on at load;
* after each step the joint's force on the held body is split into tensile (toward the gripper, from the held
  body's centre of mass) and shear parts; above ``tensileStrength``/``shearStrength`` (-1 = unbreakable) the
  hold breaks; the gripper stays on but grasps that body again only after it lost contact once;
* ``getPresence()`` is True while something is held (sampled like every Webots sensor).
* Run-time edits: ``contactPoints`` and the strengths are read when used, so a supervisor's write acts from the
  next step; a write of ``isOn`` acts as ``turnOn()``/``turnOff()`` would at the next step (the reference is
  silent: the field is the gripper's state those calls change).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from dualtwin.webots import _math3 as m3
from dualtwin.webots.device_base import Device, DeviceBinding, SampledDevice
from dualtwin.webots.fixed_link import FixedLink, body_of
from dualtwin.webots.physics import BodyRec, Simulation, SolidRec
from dualtwin.webots.physics.edit_stamps import stamps_of

__all__ = ["GripperState", "VacuumGripper", "install"]


@dataclass(eq=False)
class GripperState:
    """One VacuumGripper node's state in a simulation."""

    solid: SolidRec
    on: bool
    link: FixedLink | None = None
    contacts: dict[int, int] = field(default_factory=dict)  # body index -> contact points this pass
    released: set[int] = field(default_factory=set)  # bodies that broke free and have not let go yet
    written: int = 0  # the edit stamp of the isOn field when this state last followed it

    def field(self, name: str, default: Any) -> Any:
        return self.solid.node.fields.get(name, default)


class VacuumGrippers:
    """Per-simulation hook: contact counting, grasping and strength checks of every VacuumGripper."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.states = [
            GripperState(solid, bool(solid.node.fields.get("isOn", False)))
            for solid in sim.solids
            if solid.node.type_name == "VacuumGripper"
        ]
        for state in self.states:
            if state.solid.geoms:
                sim.set_contact_modifier(state.solid, self._counter(state))
        self.stamps = stamps_of(sim)
        sim.step_hooks.append(self.after_step)
        sim.reset_hooks.append(self.reset)

    def _counter(self, state: GripperState) -> Any:
        own = {g.ptr for g in state.solid.geoms}
        geoms = self.sim.geoms
        counts = state.contacts

        def count(contacts: Any, indices: list[int], _o1: int) -> None:
            for i in indices:
                g = contacts[i].geom
                other = g.g2 if g.g1 in own else g.g1
                rec = geoms.get(other)
                if rec is not None and rec.body is not None:
                    counts[rec.body.index] = counts.get(rec.body.index, 0) + 1

        return count

    def state_of(self, solid: SolidRec) -> GripperState | None:
        return next((s for s in self.states if s.solid is solid), None)

    def release(self, state: GripperState) -> None:
        if state.link is not None:
            state.link.destroy()
            state.link = None

    def _grasp(self, state: GripperState) -> None:
        own = body_of(state.solid)
        needed = max(int(state.field("contactPoints", 3)), 1)
        candidates = [
            (n, index) for index, n in state.contacts.items()
            if n >= needed and index not in state.released and (own is None or index != own.index)
        ]  # fmt: skip
        if not candidates:
            return
        _, index = max(candidates, key=lambda c: (c[0], -c[1]))
        held: BodyRec = self.sim.bodies[index]
        state.link = FixedLink(self.sim, held, own)

    def _follow_written_switch(self, state: GripperState) -> None:
        """A supervisor wrote ``isOn``, the field that is the gripper's state: a value other than the state acts
        as turnOn()/turnOff() would (turning off releases what it holds)."""
        stamp = self.stamps.get((id(state.solid.node), "isOn"), 0)
        if stamp == state.written:
            return
        state.written = stamp
        wanted = bool(state.field("isOn", False))
        if wanted != state.on:
            state.on = wanted
            if not wanted:
                self.release(state)

    def after_step(self) -> None:
        for state in self.states:
            self._follow_written_switch(state)
            state.released &= {i for i, n in state.contacts.items() if n > 0}
            if state.on and state.link is None:
                self._grasp(state)
            elif state.link is not None:
                held = state.link.first
                toward = m3.sub(self.sim.solid_world_pose(state.solid).t, (held.pos[0], held.pos[1], held.pos[2]))
                length = m3.norm(toward)
                axis = m3.scale(toward, 1.0 / length) if length > 0 else (0.0, 0.0, 0.0)
                tensile, shear = float(state.field("tensileStrength", -1.0)), float(state.field("shearStrength", -1.0))
                if state.link.breaks(axis, tensile, shear):
                    state.released.add(held.index)
                    self.release(state)
            state.contacts.clear()

    def reset(self) -> None:
        for state in self.states:
            self.release(state)
            state.on = bool(state.solid.node.fields.get("isOn", False))
            state.contacts.clear()
            state.released.clear()


def install(sim: Simulation) -> VacuumGrippers:
    """The simulation's vacuum-gripper hook (created once)."""
    hook = sim.extensions.get("vacuum_grippers")
    if hook is None:
        hook = sim.extensions["vacuum_grippers"] = VacuumGrippers(sim)
    return hook  # type: ignore[no-any-return]


class _Presence(SampledDevice):
    """The gripper's presence sensor (something held), sampled like every Webots sensor."""

    def __init__(self, binding: DeviceBinding, state: GripperState) -> None:
        self._state = state
        super().__init__(binding)
        self.value = False

    def _invalidate(self) -> None:
        self.value = False

    def _read(self) -> None:
        self.value = self._state.link is not None


class VacuumGripper(Device):
    """Webots ``VacuumGripper`` (module docstring)."""

    def _gripper(self) -> tuple[GripperState, _Presence]:
        cached = self.__dict__.get("_gripper_state")
        if cached is None:
            state = install(self._robot._sim).state_of(self._record.solid)
            assert state is not None
            cached = self.__dict__["_gripper_state"] = (state, _Presence(self._binding(), state))
        return cached  # type: ignore[no-any-return]

    def enablePresence(self, sampling_period: Any) -> None:
        self._gripper()[1].enable(sampling_period)

    def disablePresence(self) -> None:
        self._gripper()[1].disable()

    def getPresence(self) -> bool:
        presence = self._gripper()[1]
        presence._check_enabled("wb_vacuum_gripper_get_presence", "wb_vacuum_gripper_enable_presence")
        return bool(presence.value)

    def getPresenceSamplingPeriod(self) -> int:
        return self._gripper()[1].getSamplingPeriod()

    def isOn(self) -> bool:
        return self._gripper()[0].on

    def turnOn(self) -> None:
        self._gripper()[0].on = True

    def turnOff(self) -> None:
        state = self._gripper()[0]
        state.on = False
        install(self._robot._sim).release(state)

    on = property(isOn)
    presence = property(getPresence)
    presence_sampling_period = property(getPresenceSamplingPeriod)
