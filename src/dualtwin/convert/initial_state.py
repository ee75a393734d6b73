"""Webots' initial velocities -> a MuJoCo keyframe the converted model starts from.

A Webots Solid's ``linearVelocity`` / ``angularVelocity`` (plain hidden fields in a saved world, or a PROTO
instance's ``hidden linearVelocity_N`` / ``angularVelocity_N``, applied to its body by the PROTO expander) are the
initial velocities Webots gives the ODE body of that Solid: the linear velocity of the body's centre of mass and
its angular velocity, both in world coordinates (``docs/reference/webots-on-ode.md`` §3.1, §3.2). Joint positions
(``position``, hidden ``position_N_M``) are already the converted joints' ``ref`` (the model's ``qpos0``).

MuJoCo starts from generalised velocities instead, so the converter writes a ``<key name="webots_initial">``
whose ``qvel`` carries them (``qpos`` = ``qpos0``); the MuJoCo twin resets to it (``mj_resetDataKeyframe``), and so
can any MuJoCo program. Worlds without initial velocities get no keyframe (the MJCF is unchanged).

Decision: ``qvel`` is the momentum projection of the bodies' velocities, ``M(q)⁻¹ Σ_b J_bᵀ (m_b v_b, I_b ω_b)``
(``J_b`` the Jacobian of body b's centre of mass and rotation, ``M`` the joint-space inertia). When the Solids'
velocities are those of one rigid motion of the joints (a saved world, a thrown ball, a spinning wheel), this is
exactly that motion's ``qvel``. When they are not (each ODE body is set on its own and the joints then pull them
together), it is the closest joint motion in kinetic energy, which is what an impulsive constraint projection
(ODE's first step, without the step's gravity, motors and contacts) gives. Only the Solids that are MuJoCo bodies
carry velocities, as only Webots' ODE body roots do: a Solid merged into its parent takes its body's velocity in
Webots too (its own fields are ignored), and one without Physics outside a joint is moved kinematically by its
velocity in Webots, which the MJCF cannot carry (both are reported).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from dualtwin.twins.mujoco_state import INITIAL_KEYFRAME
from dualtwin.webots import schema
from dualtwin.webots.nodes import Node, World

__all__ = ["KEYFRAME", "add_initial_keyframe", "initial_qvel", "solid_velocity"]

#: The keyframe the converter writes and the MuJoCo twin resets to.
KEYFRAME = INITIAL_KEYFRAME


def solid_velocity(node: Node) -> tuple[np.ndarray, np.ndarray]:
    """A Solid's initial (linear, angular) velocity, world frame: its ``linearVelocity`` / ``angularVelocity``."""
    linear = np.asarray(node.get("linearVelocity", (0.0, 0.0, 0.0)) or (0.0, 0.0, 0.0), dtype=float)
    angular = np.asarray(node.get("angularVelocity", (0.0, 0.0, 0.0)) or (0.0, 0.0, 0.0), dtype=float)
    return linear, angular


def initial_qvel(model: mujoco.MjModel, velocities: dict[int, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The ``qvel`` at ``qpos0`` closest in kinetic energy to the given body velocities (body id -> (linear
    velocity of its centre of mass, angular velocity), world frame; bodies not given are at rest)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    momentum = np.zeros(model.nv)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for body in range(1, model.nbody):
        if model.body_weldid[body] == 0:
            continue  # welded to the world: it cannot move
        linear, angular = velocities.get(body, (np.zeros(3), np.zeros(3)))
        mujoco.mj_jacBodyCom(model, data, jacp, jacr, body)
        R = data.ximat[body].reshape(3, 3)
        inertia = R @ np.diag(model.body_inertia[body]) @ R.T
        momentum += jacp.T @ (model.body_mass[body] * linear) + jacr.T @ (inertia @ angular)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    qvel: np.ndarray = np.linalg.solve(full, momentum)
    return qvel


def add_initial_keyframe(spec: mujoco.MjSpec, model: mujoco.MjModel, bodies: Sequence[tuple[str, Node]],
                         world: World, warn: Callable[..., None]) -> Any:
    """Write the ``webots_initial`` keyframe when a body's Solid has an initial velocity (None otherwise).

    ``bodies``: (MuJoCo body name, the Solid it was built from) for every body the converter made. Solids with a
    velocity that are no body of their own are reported (see the module docstring).
    """
    velocities: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    roots = {id(node) for _, node in bodies}
    for name, node in bodies:
        linear, angular = solid_velocity(node)
        if linear.any() or angular.any():
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            velocities[body] = (linear, angular)
            if model.body_weldid[body] == 0:
                warn(f"body {name!r} is welded to the world (a robot without Physics): its initial velocity is "
                     "not converted", node)
    for top in world.nodes:
        for node in top.walk():
            if schema.is_solid_type(node.type_name) and id(node) not in roots and any(
                    v.any() for v in solid_velocity(node)):
                why = ("moves kinematically in Webots" if node.get("physics") is None
                       else "is merged into its parent's body, whose velocity it takes in Webots")
                warn(f"linearVelocity/angularVelocity of Solid {node.def_name or node.get('name')!r} not converted "
                     f"(it {why})", node)
    if not velocities or model.nv == 0:
        return None
    qvel = initial_qvel(model, velocities)
    return spec.add_key(name=KEYFRAME, qpos=model.qpos0.tolist(), qvel=[float(v) for v in qvel])
