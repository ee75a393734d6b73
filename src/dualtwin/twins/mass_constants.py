"""What MuJoCo derives from a model's mass distribution, kept right when the twin changes it at run time.

* **Constants.** Knobs that move masses, inertia, centres of mass or rotor armature change what the compiler derives
  from them: ``mj_setConst`` recomputes the constraint regularisation and derived masses, and the compiler's
  statistics (``stat.meaninertia``, ``stat.meanmass``: they scale solver tolerances) are computed here as the
  compiler does, so a patched MJCF reproduces the knobs exactly (:meth:`MassConstants.recompute`).
* **Simple dofs.** MuJoCo reads the mass-matrix diagonal of a "simple" dof (``dof_simplenum`` > 0: a body whose
  mass matrix is constant, such as a single joint on the world) from ``dof_M0`` and never from
  ``dof_armature``. The twin changes armature between steps (the Python law's servo adds its implicit term, the
  plugin takes the rotor inertia over); on a simple dof that change must reach ``dof_M0`` too, or it is lost and
  a stiff servo diverges (:meth:`MassConstants.write`).
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["MassConstants"]


class MassConstants:
    """The simple dofs' ``dof_M0`` as ``mj_setConst`` left it, with ``rotor`` (the armature it saw) included."""

    def __init__(self, model: mujoco.MjModel, rotor: np.ndarray) -> None:
        self.rotor = rotor  # the twin's rotor armature per dof (updated in place by the knobs)
        self._record(model)

    def _record(self, model: mujoco.MjModel) -> None:
        self.dofs = np.flatnonzero(model.dof_simplenum > 0)
        self.inertia = model.dof_M0.copy()

    def recompute(self, model: mujoco.MjModel, scratch: mujoco.MjData) -> None:
        """What a compiled model with the current masses and rotor armature would derive (module docstring).
        A compiled model has no servo armature, so that is left out while they are computed."""
        model.dof_armature[:] = self.rotor
        mujoco.mj_setConst(model, scratch)
        self._record(model)
        scratch.qpos[:] = model.qpos0
        mujoco.mj_forward(model, scratch)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, scratch, full)
        model.stat.meaninertia = float(np.trace(full)) / max(model.nv, 1)
        model.stat.meanmass = float(np.mean(model.body_mass[1:])) if model.nbody > 1 else 0.0

    def write(self, model: mujoco.MjModel, dof: int, armature: float) -> None:
        """Set one dof's armature, and a simple dof's ``dof_M0`` with it."""
        model.dof_armature[dof] = armature
        if model.dof_simplenum[dof]:
            model.dof_M0[dof] = self.inertia[dof] + (armature - self.rotor[dof])

    def restore(self, model: mujoco.MjModel) -> None:
        """Every dof back to its rotor armature."""
        model.dof_armature[:] = self.rotor
        model.dof_M0[self.dofs] = self.inertia[self.dofs]
