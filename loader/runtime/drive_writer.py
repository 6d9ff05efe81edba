"""The end of every step's stages: each DoF's law written to its PhysX joint drive (only the settings that
changed), the generalized forces gathered by the terms written with `set_qf`.

A DoF whose implicit drive damping outweighs its inertia over one step (dt D > M_ii, MuJoCo's joint-space inertia
at qpos0 with armature) takes its gathered force through the drive's velocity target instead: PhysX adds `qf`
explicitly (dt F / M_ii) before the implicit damping takes nearly all of it back, and float32 loses the difference;
in the target the force is solved with the damping. A drive with a force limit keeps `qf` (the limit must not clamp
it). Tested by tests/test_loader_limit.py::test_a_limit_force_on_a_light_damped_link_goes_through_the_drive."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .. import drive
from ..drive import DofDrive
from .dof_step import DofKey, Step


@dataclass
class DriveWriter:
    """Writes drives and `qf`; remembers, per joint, the drive settings last written (`drive.apply`)."""

    passive: dict[DofKey, DofDrive]
    inertia: dict[DofKey, float] = field(default_factory=dict)  # M_ii at qpos0 (`dof_inertia`); absent: qf only
    written: dict = field(default_factory=dict)
    name: str = "drives"

    def contribute(self, step: Step) -> None:
        for (art, dof), record in step.dofs.items():
            law = record.law
            if record.implicit_extra:
                law = dataclasses.replace(law, damping=law.damping + record.implicit_extra)
            via_damping = record.via_damping
            if (art, dof) in self.inertia and law.force_limit == np.inf and (
                    step.timestep * law.physx_damping(step.timestep) > self.inertia[(art, dof)]):
                via_damping, step.forces[art][dof] = via_damping + step.forces[art][dof], 0.0
            step.forces[art][dof] += drive.apply(step.joints[art][dof], law, record.constant, step.timestep,
                                                 via_damping, self.written, (art, dof),
                                                 step.offsets.get((art, dof), 0.0))
        for articulation, qf in zip(step.articulations, step.forces):
            if articulation.dof:
                articulation.set_qf(qf.astype(np.float32))

    def release(self, joints, articulations, timestep: float) -> None:
        """Every DoF's passive spring-damper in its drive, `qf` cleared."""
        for (art, dof), passive in self.passive.items():
            drive.apply(joints[art][dof], passive, passive.constant, timestep)
        for articulation in articulations:
            if articulation.dof:
                articulation.set_qf(np.zeros(articulation.dof, np.float32))
        self.written.clear()


def dof_inertia(model, mapping) -> dict[DofKey, float]:
    """MuJoCo's joint-space inertia diagonal (armature included) at qpos0, per hinge/slide DoF."""
    from .. import mj

    data = mj.forward_at(model)
    diagonal = data.M[model.M_rowadr + model.M_rownnz - 1]  # a row of the sparse lower triangle ends on its diagonal
    return {key: float(diagonal[d]) for key, d in mapping.mujoco_dofs().items()}
