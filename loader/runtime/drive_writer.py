"""The end of every step's stages: each DoF's law written to its PhysX joint drive (only the settings that
changed), the generalized forces gathered by the terms written with `set_qf`."""

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
    written: dict = field(default_factory=dict)
    name: str = "drives"

    def contribute(self, step: Step) -> None:
        for (art, dof), record in step.dofs.items():
            law = record.law
            if record.implicit_extra:
                law = dataclasses.replace(law, damping=law.damping + record.implicit_extra)
            step.forces[art][dof] += drive.apply(step.joints[art][dof], law, record.constant, step.timestep,
                                                 record.via_damping, self.written, (art, dof),
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
