"""Joint frictionloss on a PhysX joint drive: MuJoCo's friction row is a box-constrained solve that a drive with
damping s / (R dt), velocity target v (1 - B dt / s) and force limit F reproduces; the joint's other terms leave
the drive in the armature form. Several frictional DoFs coupled through M^-1 are approximate (listed).
Derivation: docs/mapping.md#frictionloss.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from ..drive import DofDrive
from ..errors import Notes
from .dof_step import ArmatureWriter, DofKey, Step


@dataclass(frozen=True)
class FrictionRow:
    """MuJoCo's friction row of one DoF: limit F, reference damping B, regularizer R (at qpos0)."""

    limit: float
    damping: float
    regularizer: float
    inverse_inertia: float  # (M^-1)_ii at qpos0
    armature: float  # the joint's own armature

    def scale(self, implicit_damping: float, timestep: float) -> float:
        """s = 1 + (M^-1)_ii dt D for a DoF whose implicit damping D is carried as armature."""
        return 1.0 + self.inverse_inertia * timestep * implicit_damping

    def drive(self, velocity: float, timestep: float, scale: float = 1.0) -> tuple[DofDrive, float]:
        """The drive (damping s / (R dt), force limit F) and its constant C v (1 - B dt / s) for this step."""
        damping = scale / (self.regularizer * timestep)
        return DofDrive(0.0, damping, 0.0, self.limit), damping * velocity * (1.0 - self.damping * timestep / scale)


@dataclass
class FrictionTerm:
    """The friction rows of every frictional hinge/slide DoF, carried by its drive each step (the drive's other
    terms leave it in the armature form, `dof_step.ArmatureWriter`)."""

    rows: dict[DofKey, FrictionRow]
    armature: ArmatureWriter = field(default_factory=ArmatureWriter)
    name: str = "friction"

    def contribute(self, step: Step) -> None:
        for key, row in self.rows.items():
            record = step.dofs[key]
            damping = self.armature.armature_form(step, key, row.armature, record.law, record.constant)
            record.law, record.constant = row.drive(step.v[key[0]][key[1]], step.timestep,
                                                    row.scale(damping, step.timestep))

    def release(self, joints) -> None:
        """The joints' own armature back (their friction is then not carried)."""
        for (art, dof), row in self.rows.items():
            joints[art][dof].set_armature(np.array([row.armature], np.float32))
        self.armature.written.clear()

    removed = release  # switched off: the joint's own armature, no friction


def friction_rows(model: mujoco.MjModel, mapping: Mapping) -> dict[tuple[int, int], FrictionRow]:
    """The friction row of every frictional hinge/slide DoF, by (articulation, SAPIEN dof)."""
    if not model.dof_frictionloss.any():
        return {}
    data = mj.forward_at(model)
    rows = {int(data.efc_id[i]): (float(data.efc_KBIP[i][1]), float(data.efc_R[i])) for i in range(data.nefc)
            if int(data.efc_type[i]) == int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)}
    inverse = np.diag(mj.inverse_inertia(model, data))
    out = {}
    for j, target in enumerate(mapping.joints):
        dof = int(model.jnt_dofadr[j])
        if target.kind in ("hinge", "slide") and dof in rows:
            b, regularizer = rows[dof]
            out[(target.articulation, target.dofs[0])] = FrictionRow(float(model.dof_frictionloss[dof]), b,
                                                                     regularizer, float(inverse[dof]),
                                                                     float(model.dof_armature[dof]))
    return out


def _root_dof(model: mujoco.MjModel, dof: int) -> int:
    while model.dof_parentid[dof] >= 0:
        dof = int(model.dof_parentid[dof])
    return dof


def note_coupled_friction(model: mujoco.MjModel, mapping: Mapping, laws: dict[DofKey, DofDrive], actuators,
                          rows: dict[DofKey, FrictionRow], notes: Notes) -> None:
    """List the frictionloss whose sticking phase is approximate: where another DoF moving with it (one root DoF,
    so (M^-1)_ij can be non-zero) has implicit damping (passive, actuator kv), which MuJoCo's friction rows do not
    see and PhysX's do. `laws`: every DoF's drive law with its joint actuators; `actuators`: the actuator term."""
    damped = {key for key, law in laws.items() if law.damping > 0}
    damped |= {(art, dof) for a, terms in actuators.tendon_terms.items() if actuators.actuators[a].damping
               for art, dof, _ in terms}
    dof_of = mapping.mujoco_dofs()
    for j, target in enumerate(mapping.joints):
        key = (target.articulation, target.dofs[0]) if target.kind in ("hinge", "slide") else None
        if key not in rows:
            continue
        root = _root_dof(model, dof_of[key])
        others = [k for k in damped if k != key and k in dof_of and _root_dof(model, dof_of[k]) == root]
        if others:
            name = mj.name(model, "joint", j)
            notes.approximate("joint", name, f"frictionloss {rows[key].limit:g} exact while the joint "
                              f"slides; while it sticks, MuJoCo's coupling through the implicit damping of "
                              f"{len(others)} other DoF(s) moving with it is taken on the diagonal only")
