"""Joint frictionloss on a PhysX joint drive, where the drive carries nothing else.

MuJoCo's friction row on a DoF is a box-constrained solve: f = clip(-(a0 + B v) / (A + R), -F, F), with a0 the
unconstrained acceleration, A = (M^-1)_ii, and B and R from its constraint row (`efc_KBIP`, `efc_R`; rows coupled
through M^-1 when several joints have friction). A PhysX drive with damping C, velocity target v* and force limit
F gives f = clip(C (v* - v'), -F, F) with v' = v + dt (a0 + A f), solved in the same Gauss-Seidel sweep: with
C = 1 / (R dt) and v* = v (1 - B dt) the two problems are the same. Measured on a two-link pendulum falling
against its frictionloss: 1.3e-6 rad over 1 s sliding, 3.6e-7 sticking (0.93 and 2.6 with friction dropped).
A drive holds one law: where it already carries damping, stiffness or servo gains, frictionloss is dropped and
listed (damped joints always; servo-driven joints while their actuators are on).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

from .drive import DofDrive
from .errors import Notes
from .mapping import Mapping


@dataclass(frozen=True)
class FrictionRow:
    """MuJoCo's friction row of one DoF: limit F, reference damping B, regularizer R (at qpos0)."""

    limit: float
    damping: float
    regularizer: float

    def drive(self, velocity: float, timestep: float) -> tuple[DofDrive, float]:
        """The drive (damping 1 / (R dt), force limit F) and its constant C v (1 - B dt) for this step."""
        damping = 1.0 / (self.regularizer * timestep)
        return DofDrive(0.0, damping, 0.0, self.limit), damping * velocity * (1.0 - self.damping * timestep)


def friction_rows(model: mujoco.MjModel, mapping: Mapping) -> dict[tuple[int, int], FrictionRow]:
    """The friction row of every frictional hinge/slide DoF, by (articulation, SAPIEN dof)."""
    if not model.dof_frictionloss.any():
        return {}
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    mujoco.mj_forward(model, data)
    rows = {int(data.efc_id[i]): (float(data.efc_KBIP[i][1]), float(data.efc_R[i])) for i in range(data.nefc)
            if int(data.efc_type[i]) == int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)}
    out = {}
    for j, target in enumerate(mapping.joints):
        dof = int(model.jnt_dofadr[j])
        if target.kind in ("hinge", "slide") and dof in rows:
            b, regularizer = rows[dof]
            out[(target.articulation, target.dofs[0])] = FrictionRow(float(model.dof_frictionloss[dof]), b,
                                                                     regularizer)
    return out


def note_dropped_friction(model: mujoco.MjModel, mapping: Mapping, actuation, notes: Notes) -> None:
    """List the frictionloss a drive cannot carry: always where the joint has damping or stiffness, while the
    actuators are on where one adds gains to the drive (a plain motor does not)."""
    served = {key for key, drive in actuation.drives.items() if not drive.carries_nothing()}
    served |= {(art, dof) for a, terms in actuation.tendon_terms.items() if actuation.actuators[a].damping
               for art, dof, _ in terms}
    for j, target in enumerate(mapping.joints):
        key = (target.articulation, target.dofs[0]) if target.kind in ("hinge", "slide") else None
        if key not in actuation.friction:
            continue
        name = model.joint(j).name or f"joint{j}"
        limit = actuation.friction[key].limit
        if not actuation.passive[key].carries_nothing():
            notes.drop("joint", name, f"frictionloss {limit:g} dropped: the joint's PhysX drive carries its damping "
                       "or stiffness, and PhysX has no second drive for a constant-torque friction")
        elif key in served:
            notes.approximate("joint", name, f"frictionloss {limit:g} carried by the joint's drive while its "
                              "actuators are off, dropped while they drive it")
