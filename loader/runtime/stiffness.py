"""Springs and kp a drive cannot hold: MuJoCo integrates joint springs and actuator kp explicitly, a PhysX drive
implicitly. The drive's damping D' = D - K dt reproduces MuJoCo's step while D >= K dt (`drive.py`); on a DoF where
the damping left in the drive (with the implicit tendon diagonal) cannot absorb K dt, the stiffness leaves the
drive as the explicit force constant - K q, which is what MuJoCo does. Derivation: docs/mapping.md#joint-drives.

Under Euler with `eulerdamp` disabled MuJoCo takes joint damping explicitly too: the whole damping leaves the drive
as the force -D qdot, and the stiffness with it (tests/test_loader_unconverged.py::test_explicit_damping_is_mujocos).
"""

from __future__ import annotations

from .dof_step import Step
from .term import Compilation, Term


class StiffnessTerm(Term):
    """`known`: per explicit_kv, the DoFs whose stiffness leaves the drive on a regular step (`Step.regular`).
    `explicit_damping`: MuJoCo takes joint damping explicitly (Euler with `eulerdamp` disabled)."""

    name = "stiffness"

    def __init__(self, explicit_damping: bool = False):
        self.explicit_damping = explicit_damping

    def compile(self, compilation: Compilation) -> None:
        self.known: dict[bool, object] = {}
        self.idle = not compilation.layout.keys  # no hinge or slide

    def contribute(self, step: Step) -> None:
        law = step.law
        if self.explicit_damping:
            step.force[step.layout.flat] -= law[1] * step.v[step.layout.flat]
            law[1] = 0.0
        explicit = self.known.get(step.explicit_kv) if step.regular else None
        if explicit is None:
            explicit = (~(law[1] + law[5] - law[0] * step.timestep >= 0.0)).nonzero()[0]
            if step.regular:
                self.known[step.explicit_kv] = explicit
        if explicit.size:
            flat = step.layout.flat[explicit]
            stiffness, constant = law[0], law[2]
            step.force[flat] += constant[explicit] - stiffness[explicit] * step.q[flat]
            constant[explicit] = 0.0
            stiffness[explicit] = 0.0
