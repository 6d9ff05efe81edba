"""Springs and kp a drive cannot hold: MuJoCo integrates joint springs and actuator kp explicitly, a PhysX drive
implicitly. The drive's damping D' = D - K dt reproduces MuJoCo's step while D >= K dt (`drive.py`); on a DoF where
the damping left in the drive (with the implicit tendon diagonal) cannot absorb K dt, the stiffness leaves the
drive as the explicit force constant - K q, which is what MuJoCo does. Derivation: docs/mapping.md#joint-drives.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .dof_step import Step


@dataclass
class StiffnessTerm:
    name: str = "stiffness"

    def contribute(self, step: Step) -> None:
        for (art, dof), record in step.dofs.items():
            law = record.law
            if law.damping + record.implicit_extra - law.stiffness * step.timestep >= 0.0:
                continue
            step.forces[art][dof] += record.constant - law.stiffness * step.q[art][dof]
            record.constant = 0.0
            record.law = dataclasses.replace(law, stiffness=0.0)
