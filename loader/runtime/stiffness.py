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

    def batch(self, step: Step, steps: list, terms: list) -> bool:
        """Every copy at once on a regular step, where every copy's law is the same."""
        if step.regular:
            self.contribute(step)
        return step.regular

    def contribute(self, step: Step) -> None:
        law, flat = step.law, step.layout.flat
        if self.explicit_damping:
            step.force[..., flat] -= law[1] * step.v[..., flat]
            law[1] = 0.0
        explicit = self.known.get(step.explicit_kv) if step.regular else None
        if explicit is None:
            first = law if law.ndim == 2 else law[:, 0]  # a batch's regular step: every copy's is the same
            explicit = (~(first[1] + first[5] - first[0] * step.timestep >= 0.0)).nonzero()[0]
            if step.regular:
                self.known[step.explicit_kv] = explicit
        if explicit.size:
            flat = flat[explicit]
            stiffness, constant = law[0], law[2]
            step.force[..., flat] += constant[..., explicit] - stiffness[..., explicit] * step.q[..., flat]
            constant[..., explicit] = 0.0
            stiffness[..., explicit] = 0.0
