"""A supervisor's run-time edit of a ``WorldInfo`` field that the physics reads, applied to ODE before the next
step. The reference gives the load's mapping of each field (§1.1-§1.5) and is silent on run-time writes; these
follow the rule that every field write reaches ODE at the next step, with the load's checks and ODE calls.

* ``ERP`` and ``CFM`` (§1.1): ``dWorldSetERP``/``dWorldSetCFM``; a value out of range is reset to its default
  with a warning, as at load and as WbWorldInfo does.
* ``gravity`` (§1.1): ``dWorldSetGravity`` with the vector along the world's down axis (``coordinateSystem``, read
  at load). The bodies asleep are woken (UNVERIFIED, the reference is silent: ODE itself leaves a disabled body
  where it sleeps, which under a new gravity is a body resting where it no longer could; a world loaded with the
  new gravity has every body awake). Buoyancy (:mod:`.immersion`) pushes with the new gravity.
* ``physicsDisableTime``, ``physicsDisableLinearThreshold``, ``physicsDisableAngularThreshold`` (§1.3): the world's
  auto-disable time and every body's flag, thresholds and time, set as at load (:meth:`SceneBuilder._set_auto_disable`);
  a time of 0 turns sleeping off and wakes the bodies asleep (a world loaded that way has none asleep), and the
  near callback's rule 9 (§2.3, no contact between sleeping bodies) follows the feature on or off. ODE's own
  idle count of a body goes on (``dBodySetAutoDisableTime`` does not restart it): a body resting since before
  the edit sleeps when its count runs out, one that moves afterwards counts the new time from its last motion.
* ``basicTimeStep`` (§1.1, §1.5): the following steps are ``dWorldStep``\\ s of the new length (a value ≤ 0 is reset
  to 32 with a warning, as at load); the simulated time goes on from where it was, ``Robot.getBasicTimeStep``
  returns the new value, and what Webots converts with the step length is converted again: the world's and the
  bodies' damping (§1.4) and the joints' spring and damper rows and Hinge2 suspensions (§4.4, §4.5, ERP and CFM
  from h·K and B). A controller's ``step(ms)`` still advances until ``ms`` of simulated time have passed, in
  steps of the new length (a duration that is no longer a multiple ends at the first step boundary past it).

A ``simulationReset`` puts the load values back and applies them again (``Simulation.reset``).
"""

from __future__ import annotations

from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode, world_frame
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.mass_edits import MassEdits
from dualtwin.webots.physics.records import field_or as _f

__all__ = ["SLEEP_FIELDS", "WorldInfoEdits", "gravity_vector"]

#: The WorldInfo fields of auto-disable (§1.3).
SLEEP_FIELDS = frozenset({"physicsDisableTime", "physicsDisableLinearThreshold", "physicsDisableAngularThreshold"})

DEFAULT_BASIC_TIME_STEP = 32.0  # ms, §1.1: what a basicTimeStep ≤ 0 is reset to


def gravity_vector(g: float, coordinate_system: str) -> m3.Vec3:
    """WorldInfo's scalar ``gravity`` as the world vector along the coordinate system's down axis (§1.1)."""
    up = world_frame.axes(coordinate_system).up
    return (-g * up[0] if up[0] else 0.0, -g * up[1] if up[1] else 0.0, -g * up[2] if up[2] else 0.0)


def sleep_settings(info: Node | None) -> tuple[float, float, float]:
    """WorldInfo's ``physicsDisableTime`` and its linear and angular thresholds (§1.3), at load and after an edit."""
    return (float(_f(info, "physicsDisableTime", 1.0)), float(_f(info, "physicsDisableLinearThreshold", 0.01)),
            float(_f(info, "physicsDisableAngularThreshold", 0.01)))


class WorldInfoEdits(MassEdits):
    """Run-time edits of WorldInfo's physics fields (see the module docstring)."""

    def _apply_world_info(self, node: Node, name: str) -> bool:
        if name in ("ERP", "CFM"):
            self._set_erp_cfm(node, name)
            return True
        if name == "gravity":
            self.gravity = gravity_vector(float(_f(node, "gravity", 9.81)), self.coordinate_system)
            self._lib.dWorldSetGravity(self._world, *self.gravity)
            buoyancy = self.extensions.get("buoyancy")
            if buoyancy is not None:
                buoyancy.gravity = self.gravity
            self._wake_all()
            return True
        if name in SLEEP_FIELDS:
            self._set_sleep(node)
            return True
        if name == "basicTimeStep":
            self._set_basic_time_step(node)
            return True
        return False

    def _set_erp_cfm(self, node: Node, name: str) -> None:
        # Checked as at load and as Webots' WorldInfo does, which resets a value out of range to its default:
        # an ERP of -1e308 written at run time stopped ODE inside its step (found by fuzzing the API)
        number = float(node.fields[name])
        if name == "ERP" and not 0.0 <= number <= 1.0 or name == "CFM" and not number > 0.0:
            default = 0.2 if name == "ERP" else 0.00001
            self.warn(f"WorldInfo.{name} {number:g} is out of range ({'[0, 1]' if name == 'ERP' else '> 0'}); "
                      f"reset to {default:g}")
            number = node.fields[name] = default
        if name == "ERP":
            self.erp = number
            self._lib.dWorldSetERP(self._world, number)
        else:
            self.cfm = number
            self._lib.dWorldSetCFM(self._world, number)

    def _set_sleep(self, node: Node) -> None:
        """§1.3 set again from the three fields, on the world and on every body, as at load."""
        self.disable_time, self.disable_lin, self.disable_ang = sleep_settings(node)
        self._lib.dWorldSetAutoDisableTime(self._world, max(self.disable_time, 0.0))
        for body in self.bodies:
            if not body.removed:
                self._set_auto_disable(body)
        if self._auto_disable and self.disable_time <= 0:
            self._wake_all()  # (before the flag goes: _wake_all wakes only while sleeping is on)
        auto_disable = self.disable_time > 0
        if auto_disable != self._auto_disable:
            self._auto_disable = auto_disable
            self._near_cb = ode.NearCallback(self._make_near_callback())  # rule 9 is tested only while sleeping is on

    def _wake_all(self) -> None:
        """Enable every body asleep."""
        if not self._auto_disable:
            return
        enabled = self._enabled
        for body in self.bodies:
            if not body.removed and not enabled[body.index]:
                self._lib.dBodyEnable(body.ptr)
                enabled[body.index] = True

    def _set_basic_time_step(self, node: Node) -> None:
        step_ms = float(node.fields["basicTimeStep"])
        if not step_ms > 0.0:
            self.warn(f"WorldInfo.basicTimeStep {step_ms:g} must be positive; reset to {DEFAULT_BASIC_TIME_STEP:g}")
            step_ms = node.fields["basicTimeStep"] = DEFAULT_BASIC_TIME_STEP
        if step_ms == self.basic_time_step:
            return
        # the time reached so far stays; the steps from here on are of the new length
        self._time_base = self.time
        self._steps_base = self.step_count
        self.basic_time_step = step_ms
        self.dt = step_ms * 0.001
        self._refresh_damping()  # §1.4: per-step damping from the fraction lost per second
        for joint in self.joints:
            if joint.spring or joint.spring2:
                self.rebuild_springs(joint)  # §4.5: ERP = hK/(hK + B), CFM = 1/(hK + B)
            if joint.kind == "hinge2" and joint.ptr:
                self._set_hinge2_suspension(joint)  # §4.4: the same conversion
