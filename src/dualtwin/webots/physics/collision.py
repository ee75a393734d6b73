"""The collision pass (§2): ContactProperties turned into pre-filled ``dContact`` arrays, the pair filters of
§2.3 (cached per geom pair), the near callback creating contact joints into per-body double-buffered groups.

Not to be confused with :mod:`dualtwin.webots.contacts`, which reads the contact points of a finished step
for the Supervisor API."""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Iterable
from typing import Any

from dualtwin.interrupts import enter_native_callbacks, leave_native_callbacks
from dualtwin.webots import _math3 as m3
from dualtwin.webots import ode
from dualtwin.webots.nodes import Node
from dualtwin.webots.physics.joints import JointBuilder
from dualtwin.webots.physics.records import (
    DEFAULT_CONTACT_CAPACITY,
    GEOM_OFFSET,
    SIZEOF_CONTACT,
    BodyRec,
    GeomRec,
    SolidRec,
    Surface,
)
from dualtwin.webots.physics.records import (
    field_or as _f,
)

#: the static environment's place in a run-time link's pair of body indices (:meth:`CollisionPass.link_bodies`)
WORLD_INDEX = -1


class CollisionPass(JointBuilder):
    """Contact surfaces, pair filters and the near callback (see the module docstring)."""

    def _init_contacts(self) -> None:
        self._surfaces = {}
        self._default_surface = self._make_surface(None)
        self._plans = {}
        self._run_time_links = {}
        self._contact_modifiers = {}
        self._buffer = 0
        self._used = [[], []]
        self._callback_error = None
        self._auto_disable = self.disable_time > 0
        self._enabled = [True] * len(self.bodies)
        self._near_cb = ode.NearCallback(self._make_near_callback())

    def _make_surface(self, cp: Node | None) -> Surface:
        coulomb = list(_f(cp, "coulombFriction", [1.0]) or [1.0])
        slip = list(_f(cp, "forceDependentSlip", [0.0]) or [0.0])
        rolling = tuple(_f(cp, "rollingFriction", (0.0, 0.0, 0.0)))
        bounce = float(_f(cp, "bounce", 0.5))
        s = ode.dSurfaceParameters()
        mode = ode.dContactApprox1 | ode.dContactSoftCFM | ode.dContactSoftERP
        if bounce != 0.0:
            mode |= ode.dContactBounce
        mu = float(coulomb[0])
        s.mu = ode.dInfinity if mu == -1 else mu
        # Webots leaves mu2 at 0 unless friction is asymmetric. ODE's dContactAxisDep, set for rho2/rhoN, is the
        # same bit as dContactMu2: with it ODE uses mu2 (= 0) along the second friction direction (§2.2).
        s.mu2 = 0.0
        if float(slip[0]) != 0.0:
            mode |= ode.dContactSlip1 | ode.dContactSlip2
            s.slip1 = s.slip2 = float(slip[0])
        rho, rho2, rho_n = (float(v) for v in rolling)
        if rho > 0 or rho2 > 0 or rho_n > 0:
            mode |= ode.dContactRolling
            if rho2 > 0 or rho_n > 0:
                mode |= ode.dContactAxisDep
        s.rho, s.rho2, s.rhoN = (ode.dInfinity if v == -1 else v for v in (rho, rho2, rho_n))
        s.bounce = bounce
        s.bounce_vel = float(_f(cp, "bounceVelocity", 0.01))
        s.soft_erp = float(_f(cp, "softERP", 0.2))
        s.soft_cfm = float(_f(cp, "softCFM", 0.001))
        s.mode = mode
        asymmetric = None
        if cp is not None and len(coulomb) > 1:
            values = tuple(ode.dInfinity if float(v) == -1 else float(v) for v in coulomb[:4])
            rotation = tuple(float(v) for v in _f(cp, "frictionRotation", (0.0, 0.0)))
            asymmetric = (values, str(_f(cp, "material1", "default")), (rotation[0], rotation[1]))
        if cp is not None and len(slip) > 1:
            self.warn("asymmetric forceDependentSlip is approximated by its first value")
        capacity = DEFAULT_CONTACT_CAPACITY
        arr = self._contact_array(s, capacity)
        return Surface(arr, capacity, int(_f(cp, "maxContactJoints", 10)), s, asymmetric)

    # -- asymmetric friction (§2.2)

    def _friction_direction(self, gr: GeomRec, normal: m3.Vec3) -> m3.Vec3 | None:
        """The geometry's first friction direction (its texture's U direction) at a contact of this normal, in the
        world frame; None for geometries without one (Sphere, Capsule, meshes)."""
        if gr.kind not in ("Box", "Plane", "Cylinder"):
            return None
        if gr.is_plane:
            R = (self.solid_world_pose(gr.solid) * gr.local).R
        else:
            r = ctypes.cast(self._lib.dGeomGetRotation(gr.ptr), ctypes.POINTER(ctypes.c_double))
            R = (r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10])
        local_normal = m3.mat_t_vec(R, normal)
        ax, ay, az = (abs(v) for v in local_normal)
        if gr.kind == "Box" and ax > ay and ax > az:
            local = (0.0, 1.0, 0.0)  # a face across x: U runs along y
        elif gr.kind == "Cylinder" and not (az > ax and az > ay):
            local = (0.0, 0.0, 1.0)  # the side: along the axis
        else:
            local = (1.0, 0.0, 0.0)  # a face across z (or y), a cap, a plane: along x
        d = m3.mat_vec(R, local)
        d = m3.sub(d, m3.scale(normal, m3.dot(d, normal)))  # into the contact plane
        n = m3.norm(d)
        return m3.scale(d, 1.0 / n) if n > 1e-12 else None

    def _asymmetric_modifier(self, g1: GeomRec, g2: GeomRec, surface: Surface) -> Callable[[Any, list[int], int], None]:
        """Per contact: fdir1 from material1's geometry turned by −frictionRotation about the normal, and mu/mu2
        combined from both solids' coefficients and the angle α between their friction directions (§2.2):
        2 values (both solids): mu = m0 + m0|cos α| + m1|sin α|, mu2 = m1 + m0|sin α| + m1|cos α|; 3 values:
        mu = m0 + m2, mu2 = m1 + m2; 4 values: mu = m0 + m2|cos α| + m3|sin α|, mu2 = m1 + m2|sin α| + m3|cos α|.
        Falls back to the symmetric surface when a geometry has no friction direction."""
        values, material1, rotation = surface.asymmetric  # type: ignore[misc]
        first, second = (g1, g2) if g1.solid.material == material1 else (g2, g1)

        def turned(d: m3.Vec3, normal: m3.Vec3, angle: float) -> m3.Vec3:
            return m3.mat_vec(m3.rot_axis_angle((*normal, -angle)), d) if angle else d

        def modify(arr: Any, indices: list[int], _o1: int) -> None:
            for i in indices:
                c = arr[i]
                normal = (c.geom.normal[0], c.geom.normal[1], c.geom.normal[2])
                d1 = self._friction_direction(first, normal)
                d2 = self._friction_direction(second, normal)
                if d1 is None or d2 is None:
                    continue
                d1, d2 = turned(d1, normal, rotation[0]), turned(d2, normal, rotation[1])
                cos_a = abs(m3.dot(d1, d2))
                sin_a = abs(m3.dot(m3.cross(d1, d2), normal))
                if len(values) == 2:
                    m0, m1 = values
                    mu, mu2 = m0 + m0 * cos_a + m1 * sin_a, m1 + m0 * sin_a + m1 * cos_a
                elif len(values) == 3:
                    mu, mu2 = values[0] + values[2], values[1] + values[2]
                else:
                    m0, m1, m2, m3_ = values
                    mu, mu2 = m0 + m2 * cos_a + m3_ * sin_a, m1 + m2 * sin_a + m3_ * cos_a
                c.surface.mode |= ode.dContactFDir1 | ode.dContactMu2
                c.surface.mu, c.surface.mu2 = mu, mu2
                c.fdir1[0], c.fdir1[1], c.fdir1[2] = d1

        return modify

    @staticmethod
    def _contact_array(s: ode.dSurfaceParameters, capacity: int) -> Any:
        arr = (ode.dContact * capacity)()
        for i in range(capacity):
            arr[i].surface = s
        return arr

    def contact_properties_changed(self) -> None:
        """``WorldInfo.contactProperties`` gained or lost a node (a supervisor's import or removal, a reset): the
        collision passes from now on match the list as it is (§2.1: the first matching node wins)."""
        info = self.world.world_info()
        listed = _f(info, "contactProperties", []) or []
        self.contact_properties = [cp for cp in listed if isinstance(cp, Node)]
        self._surfaces.clear()
        self._plans.clear()  # the pairs' plans hold the surface they were first matched with

    def contact_properties_for(self, material1: str, material2: str) -> Node | None:
        """§2.1: the first ContactProperties matching the two materials in either order."""
        for cp in self.contact_properties:
            m1, m2 = str(_f(cp, "material1", "default")), str(_f(cp, "material2", "default"))
            if (m1 == material1 and m2 == material2) or (m1 == material2 and m2 == material1):
                return cp
        return None

    def _surface_for(self, material1: str, material2: str) -> Surface:
        cp = self.contact_properties_for(material1, material2)
        if cp is None:
            return self._default_surface
        surface = self._surfaces.get(id(cp))
        if surface is None:
            surface = self._surfaces[id(cp)] = self._make_surface(cp)
        return surface

    def link_bodies(self, b1: BodyRec, b2: BodyRec | None, linked: bool) -> None:
        """Declare (or undo) a joint created at run time between two bodies (a locked Connector, a vacuum
        gripper's hold): like any jointed pair, their geoms then stop colliding. ``b2`` None is the static
        environment: while so jointed, ``b1`` collides with no static geom (§2.3 rule 6, as a body jointed to the
        world at load). Counted: two holds of one pair (two suction cups, a gripper on a locked connector) keep it
        filtered until the last is undone, as ODE's test is whether any joint connects the two."""
        key = frozenset((b1.index, WORLD_INDEX if b2 is None else b2.index))
        count = self._run_time_links.get(key, 0) + (1 if linked else -1)
        if count > 0:
            self._run_time_links[key] = count
        else:
            self._run_time_links.pop(key, None)
        self._plans.clear()

    def _bodies_connected(self, b1: BodyRec, b2: BodyRec) -> bool:
        if self._run_time_links and frozenset((b1.index, b2.index)) in self._run_time_links:
            return True
        for j in b1.joints:
            if (j.parent_body is b1 and j.child_body is b2) or (j.parent_body is b2 and j.child_body is b1):
                return True
        return (b1.fixed_to is b2 and b1.fixed_joint != 0) or (b2.fixed_to is b1 and b2.fixed_joint != 0)

    def _same_anchor_chain(self, b1: BodyRec, b2: BodyRec) -> bool:
        """§2.3 rule 7: b1 and b2 linked by hinge-like joints that all share one anchor."""
        for first in b1.joints:
            if first.kind not in ("hinge", "hinge2", "ball") or first.parent_body is None:
                continue
            anchor = self._joint_world_frame(first).apply(first.anchor_local)
            seen = {b1.index}
            frontier = [b1]
            while frontier:
                b = frontier.pop()
                for j in b.joints:
                    if j.kind not in ("hinge", "hinge2", "ball") or j.parent_body is None:
                        continue
                    a = self._joint_world_frame(j).apply(j.anchor_local)
                    if m3.norm(m3.sub(a, anchor)) > 1e-9:
                        continue
                    other = j.child_body if j.parent_body is b else j.parent_body
                    if other is None or other.index in seen:
                        continue
                    if other is b2:
                        return True
                    seen.add(other.index)
                    frontier.append(other)
        return False

    def _plan_pair(self, o1: int, o2: int) -> Any:
        g1, g2 = self.geoms.get(o1), self.geoms.get(o2)
        if g1 is None or g2 is None:
            return False
        b1, b2 = g1.body, g2.body
        if b1 is None and b2 is None:
            return False  # rule 5
        r1, r2 = g1.solid.robot, g2.solid.robot
        if r1 is not None and r1 is r2 and not r1.self_collision:
            return False  # rule 4
        if b1 is not None and b2 is not None:
            if b1 is b2 or self._bodies_connected(b1, b2) or self._same_anchor_chain(b1, b2):
                return False  # rules 6 and 7
        else:
            b = b1 if b1 is not None else b2
            assert b is not None
            if b.attached_to_world or (
                    self._run_time_links and frozenset((b.index, WORLD_INDEX)) in self._run_time_links):
                return False  # rule 6: a body jointed to the static environment ignores static geoms
        surface = self._surface_for(g1.solid.material, g2.solid.material)
        owner = b1 if b1 is not None else b2
        modifier = self._contact_modifiers.get(id(g1.solid)) or self._contact_modifiers.get(id(g2.solid))
        if surface.asymmetric is not None:
            asymmetric = self._asymmetric_modifier(g1, g2, surface)
            if modifier is None:
                modifier = asymmetric
            else:
                track = modifier

                def modifier(arr: Any, indices: list[int], o1: int) -> None:
                    asymmetric(arr, indices, o1)
                    track(arr, indices, o1)
        return (
            surface,
            owner,
            b1.ptr if b1 is not None else None,
            b2.ptr if b2 is not None else None,
            b1.index if b1 is not None else -1,
            b2.index if b2 is not None else -1,
            modifier,
        )

    def set_contact_modifier(self, solid: SolidRec, modifier: Callable[[Any, list[int], int], None]) -> None:
        """Let ``modifier(contacts, indices, o1)`` edit the ``dContact`` entries of every pair involving the
        Solid's geoms before their contact joints are created (Track belts set a surface velocity this way);
        the entries are restored afterwards. ``o1`` is the pair's first geom."""
        self._contact_modifiers[id(solid)] = modifier
        self._plans.clear()

    def _make_near_callback(self) -> Callable[[Any, Any, Any], None]:
        plans = self._plans
        plans_get = plans.get
        collide = self._lib.dCollide
        create = self._lib.dJointCreateContact
        attach = self._lib.dJointAttach
        world = self._world
        plan_pair = self._plan_pair
        enabled = self._enabled
        sizeof = SIZEOF_CONTACT
        geom_offset = GEOM_OFFSET
        addressof = ctypes.addressof
        auto_disable = self._auto_disable  # set once, just before this callback is made (_init_contacts)

        def near(_data: Any, o1: int, o2: int) -> None:
            try:
                key = (o1, o2)
                plan = plans_get(key)
                if plan is None:
                    plan = plans[key] = plan_pair(o1, o2)
                if plan is False:
                    return
                surface, owner, p1, p2, i1, i2, modifier = plan
                if auto_disable:
                    e1 = enabled[i1] if i1 >= 0 else None
                    e2 = enabled[i2] if i2 >= 0 else None
                    if (e1 is None or not e1) and (e2 is None or not e2):
                        return  # rule 9 (both disabled, or body-less vs disabled)
                arr = surface.contacts
                base = addressof(arr)
                cap = surface.capacity
                n = collide(o1, o2, cap, base + geom_offset, sizeof)
                if n == 0:
                    return
                while n >= cap and cap < 0xFFFF:
                    cap = min(cap * 10, 0xFFFF)
                    surface.contacts = arr = self._contact_array(surface.template, cap)
                    surface.capacity = cap
                    base = addressof(arr)
                    n = collide(o1, o2, cap, base + geom_offset, sizeof)
                group = owner.groups[self._buffer]
                if n > surface.max_joints:
                    order = sorted(range(n), key=lambda i: -arr[i].geom.depth)[: surface.max_joints]
                    indices: Iterable[int] = sorted(order)
                else:
                    indices = range(n)
                if modifier is not None:
                    indices = list(indices)
                    modifier(arr, indices, o1)
                for i in indices:
                    attach(create(world, group, base + i * sizeof), p1, p2)  # ODE copies the dContact
                if modifier is not None:
                    for i in indices:
                        arr[i].surface = surface.template
                        arr[i].fdir1[0] = arr[i].fdir1[1] = arr[i].fdir1[2] = 0.0
                self._used[self._buffer].append(owner)
            except BaseException as exc:  # a ctypes callback cannot raise: re-raised after dSpaceCollide
                self._callback_error = exc

        return near

    def space_order(self) -> dict[int, int]:
        """Each geom's index in the top space's list. ODE's simple space hands a pair to the near callback as
        (earlier, later) in this list, which moving bodies reorder (a moved geom goes to the front); some ODE
        colliders (box-box with deep penetration) find contacts in one argument order and not the other, so a
        query that must agree with the collision pass (bumpers, contact points) calls ``dCollide`` in this order."""
        lib = self._lib
        space = self._space
        return {lib.dSpaceGetGeom(space, i): i for i in range(lib.dSpaceGetNumGeoms(space))}

    def _collide(self) -> None:
        enter_native_callbacks()  # a Ctrl-C in the near callback would be printed and lost: held until here
        try:
            self._lib.dSpaceCollide(self._space, None, self._near_cb)
        finally:
            leave_native_callbacks()
        if self._callback_error is not None:
            exc, self._callback_error = self._callback_error, None
            raise exc
