"""Fixed-tendon actuators: J^T f with f MuJoCo's actuator force at the tendon's length and rate now. MuJoCo's
implicit step holds only the diagonal of kv J^T J (none once its forcerange clamps it): that joins the drives, and
the explicit force gets it back at the current rate
(tests/test_loader_actuators.py::test_a_tendon_servo_matches_mujoco)."""

from __future__ import annotations

import numpy as np

from ..build.actuators import ActuatorMap
from .actuator_laws import ActuatorLaws
from .dof_step import DofLayout, Step


class TendonActuators:
    """The mapped tendon actuators (`laws`) and their tendons' terms: per term its actuator (`owner`), joint
    position (`flat`), drive column and coefficient."""

    def __init__(self, actuators: list[ActuatorMap], terms: dict[int, list[tuple[int, int, float]]],
                 layout: DofLayout):
        order = list(terms)
        self.laws = ActuatorLaws(actuators, order)
        rows = [(k, (art, dof), c) for k, a in enumerate(order) for art, dof, c in terms[a]]
        self.owner = np.array([k for k, _, _ in rows], dtype=int)
        self.flat = layout.flat_of([key for _, key, _ in rows])
        self.drive = layout.drive_of([key for _, key, _ in rows])
        self.coefficient = np.array([c for _, _, c in rows], dtype=np.float64)
        self.geared = self.laws.gear[self.owner] * self.coefficient  # gear c per term

    def contribute(self, step: Step, implicit_kv) -> None:
        """`implicit_kv(damping, saturated)`: the kv MuJoCo's implicit step keeps, per actuator."""
        laws, owner, c, count = self.laws, self.owner, self.coefficient, len(self.laws)
        q, v = step.q[self.flat], step.v[self.flat]
        length = laws.gear * np.bincount(owner, c * q, minlength=count)
        speed = laws.gear * np.bincount(owner, c * v, minlength=count)
        unclamped = laws.unclamped(step.inputs[laws.indices], length, speed)
        force = laws.clamped(unclamped)
        implicit = np.zeros(count)
        saturated = force != unclamped
        if np.count_nonzero(saturated):
            step.regular = False
        if not step.explicit_kv:
            implicit = implicit + implicit_kv(laws.damping, saturated)
        implicit = implicit[owner]
        np.add.at(step.force, self.flat, self.geared * force[owner] + implicit * c * c * v)
        np.add.at(step.law[5], self.drive, implicit * c * c)
