"""Fixed-tendon actuators: J^T f with f MuJoCo's actuator force at the tendon's length and rate now. MuJoCo's
implicitfast holds the whole kv J^T J implicitly (none once its forcerange clamps it); a drive holds one DoF, so the
diagonal joins the drives, the explicit force gets it back at the current rate, and the off-diagonal part stays
explicit (`tendons.COUPLED_DAMPING` notes it) (tests/test_loader_actuators.py::test_a_tendon_servo_matches_mujoco)."""

from __future__ import annotations

import numpy as np

from ..build.actuators import ActuatorMap
from .actuator_laws import ActuatorLaws
from .dof_step import DofLayout, Step


class TendonActuators:
    """The mapped tendon actuators (`laws`) and their tendons' terms: per term its actuator (`owner`), joint
    position (`flat`), drive column and coefficient, and the implicit diagonal kv c^2 while no forcerange
    clamps (`diagonal`)."""

    def __init__(self, actuators: list[ActuatorMap], terms: dict[int, list[tuple[int, int, float]]],
                 layout: DofLayout, implicit_kv):
        order = list(terms)
        self.laws = ActuatorLaws(actuators, order)
        rows = [(k, (art, dof), c) for k, a in enumerate(order) for art, dof, c in terms[a]]
        self.owner = np.array([k for k, _, _ in rows], dtype=int)
        self.flat = layout.flat_of([key for _, key, _ in rows])
        self.drive = layout.drive_of([key for _, key, _ in rows])
        self.coefficient = np.array([c for _, _, c in rows], dtype=np.float64)
        self.geared = self.laws.gear[self.owner] * self.coefficient  # gear c per term
        self.implicit_kv = implicit_kv  # (damping, saturated) -> the kv MuJoCo's implicit step keeps
        c, count = self.coefficient, len(self.laws)
        self.diagonal = (np.zeros(count) + implicit_kv(self.laws.damping, np.zeros(count, bool)))[self.owner] * c * c
        self.unique = len(set(self.flat.tolist())) == self.flat.size  # no DoF in two terms: no sums

    def contribute(self, step: Step) -> None:
        laws, owner, c, count = self.laws, self.owner, self.coefficient, len(self.laws)
        q, v = step.q[self.flat], step.v[self.flat]
        length = laws.gear * np.bincount(owner, c * q, minlength=count)
        speed = laws.gear * np.bincount(owner, c * v, minlength=count)
        unclamped = laws.unclamped(step.inputs[laws.indices], length, speed)
        force = laws.clamped(unclamped)
        saturated = force != unclamped
        clamped = bool(np.count_nonzero(saturated))
        if clamped:
            step.regular = False
        if step.explicit_kv:
            diagonal = None  # kv explicit: nothing joins the drives
        elif clamped:
            diagonal = (np.zeros(count) + self.implicit_kv(laws.damping, saturated))[owner] * c * c
        else:
            diagonal = self.diagonal
        term_force = self.geared * force[owner]
        if diagonal is not None:
            term_force += diagonal * v
        if self.unique:
            step.force[self.flat] += term_force
            if diagonal is not None:
                extra = step.law[5]
                extra[self.drive] += diagonal
        else:
            np.add.at(step.force, self.flat, term_force)
            if diagonal is not None:
                np.add.at(step.law[5], self.drive, diagonal)
