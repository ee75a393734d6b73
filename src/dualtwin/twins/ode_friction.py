"""ODE's friction pyramid (Webots' ``dContactApprox1``) in MuJoCo.

Webots creates every contact with ``dContactApprox1``, ``mu2 = mu`` and the friction directions ``p, q`` of
``dPlaneSpace(normal)``: each friction row is bounded separately, ``|f_p| <= mu N`` and ``|f_q| <= mu N``. That
is a square of half-width ``mu N`` aligned with dPlaneSpace's axes (world x and y for a horizontal floor),
which allows ``sqrt(2) mu N`` diagonally, so the result depends on the robot's heading. MuJoCo's pyramidal
cone bounds ``|f_1| + |f_2| <= mu N`` in its contact frame (a diamond), its elliptic cone is a circle.

The diamond becomes the square exactly in a tangent frame turned 45 degrees about the normal,
``t_1 = (p + q)/sqrt(2)`` and ``t_2 = (q - p)/sqrt(2)``, with ``sqrt(2) mu``: then ``|f_1| + |f_2| =
(|f_p + f_q| + |f_q - f_p|)/sqrt(2) = sqrt(2) max(|f_p|, |f_q|) <= sqrt(2) mu N``.

MuJoCo writes the contact frames in ``mj_collision``, inside ``mj_step1``. So a step is ``mj_step1``, the
frames and frictions edited, the contact-dependent rest of the position and velocity stages redone
(:func:`rebuild_constraints`), then ``mj_step2``. A model asks for it with
``<custom><text name="webots_contact" data="approx1"/></custom>`` and must use the pyramidal cone. Exact for
condim 3 contacts (torsional and rolling friction would join the pyramid's sum).

What it does not change: in MuJoCo (either cone) a sliding slab hops, losing all its contacts every few
steps, and the Pioneer's wheels chatter while they scrub; in ODE neither does (README, Pioneer section).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from dualtwin.errors import DualtwinError

#: The custom text element that selects the contact semantics, and its one value.
CONTACT_TEXT = "webots_contact"
APPROX1 = "approx1"

_SQRT2 = math.sqrt(2.0)
_SQRT1_2 = math.sqrt(0.5)
_CACHED_SETS = 64


def contact_semantics(model: mujoco.MjModel, origin: str) -> str | None:
    """The model's ``webots_contact`` text (``"approx1"``), or None when it has none.

    Raises:
        DualtwinError: An unknown value, or ``approx1`` without ``cone="pyramidal"``.
    """
    index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, CONTACT_TEXT)
    if index < 0:
        return None
    adr, size = int(model.text_adr[index]), int(model.text_size[index])
    value = bytes(model.text_data[adr:adr + size]).rstrip(b"\0").decode().strip()
    if value != APPROX1:
        raise DualtwinError(f"{origin}: custom text {CONTACT_TEXT!r} is {value!r}; the only contact semantics "
                            f"is {APPROX1!r} (Webots' friction pyramid)")
    if model.opt.cone != mujoco.mjtCone.mjCONE_PYRAMIDAL:
        raise DualtwinError(f"{origin}: {CONTACT_TEXT}={APPROX1!r} needs option cone=\"pyramidal\" "
                            "(the square friction limit is built from MuJoCo's pyramid)")
    return value


def plane_space(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ODE's ``dPlaneSpace`` for each row of ``normals`` (unit vectors): ``p`` and ``q = n x p``."""
    n0, n1, n2 = normals[:, 0], normals[:, 1], normals[:, 2]
    # ODE takes p in the y-z plane when the normal is mostly along z, else in the x-y plane.
    along_z = np.abs(n2) > _SQRT1_2
    a = np.where(along_z, n1 * n1 + n2 * n2, n0 * n0 + n1 * n1)
    k = 1.0 / np.sqrt(a)
    zero = np.zeros_like(n0)
    p = np.where(along_z[:, None], np.stack([zero, -n2 * k, n1 * k], axis=1),
                 np.stack([-n1 * k, n0 * k, zero], axis=1))
    q = np.where(along_z[:, None], np.stack([a * k, -n0 * p[:, 2], n0 * p[:, 1]], axis=1),
                 np.stack([-n2 * p[:, 1], n2 * p[:, 0], a * k], axis=1))
    return p, q


def rebuild_constraints(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Redo what ``mj_step1`` computed from the contacts after ``mj_collision``.

    In ``mj_fwdPosition``: the constraint rows and islands, and the solver's projections
    (``mj_transmission`` in between does not read contacts); in ``mj_fwdVelocity``: the constraint velocities
    and reference accelerations. Without an edit in between, ``mj_step1``, this and ``mj_step2`` is
    ``mj_step`` bit for bit (tests/twins/test_ode_friction.py).
    """
    mujoco.mj_makeConstraint(m, d)
    mujoco.mj_island(m, d)
    mujoco.mj_projectConstraint(m, d)
    mujoco.mj_referenceConstraint(m, d)


class FrictionBox:
    """``step(m, d)``: ``mj_step`` with ODE's square friction limit on every contact."""

    def __init__(self) -> None:
        # A robot on one floor has the same few contact sets step after step (all normals along the floor's,
        # some of the points lifting off): their tangents are computed once.
        self._tangents: dict[bytes, np.ndarray] = {}

    def apply(self, d: mujoco.MjData) -> None:
        """Turn each contact's tangent frame to the square's diagonals and scale its friction by sqrt(2)."""
        contact = d.contact
        frame = contact.frame
        key = frame[:, :3].tobytes()
        tangents = self._tangents.get(key)
        if tangents is None:
            if len(self._tangents) >= _CACHED_SETS:  # normals that keep changing (uneven ground)
                self._tangents.clear()
            p, q = plane_space(frame[:, :3])
            tangents = self._tangents[key] = np.concatenate([(p + q) * _SQRT1_2, (q - p) * _SQRT1_2], axis=1)
        frame[:, 3:] = tangents
        contact.friction[:, :2] *= _SQRT2

    def step(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        self.step1(m, d)
        mujoco.mj_step2(m, d)

    def step1(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """The step's first half (``mj_step1``) with the square friction limit; ``mj_step2`` finishes it."""
        mujoco.mj_step1(m, d)
        if d.ncon:
            self.apply(d)
            rebuild_constraints(m, d)
