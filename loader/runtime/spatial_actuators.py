"""Actuators on spatial tendons: MuJoCo's force law at the tendon's length and rate now, along the path MuJoCo
computes at SAPIEN's pose (`tendon_paths.py`), applied as J^T gear f. Euler takes kv explicitly; MuJoCo's
implicitfast holds kv's whole J^T J implicitly (none once its forcerange clamps it), of which the drives take the
diagonal (tests/test_loader_spatial_tendons.py::test_a_spatial_tendon_servo_matches_mujoco)."""

from __future__ import annotations

import numpy as np

from ..build.actuators import ActuatorMap
from .actuator_laws import ActuatorLaws
from .dof_step import Step
from .integrated import RootPush
from .tendon_paths import TendonPaths


class SpatialActuators:
    """The mapped actuators on spatial tendons (`tendons`: actuator id -> tendon id) along `paths`."""

    def __init__(self, actuators: list[ActuatorMap], tendons: dict[int, int], paths: TendonPaths, implicit_kv):
        order = list(tendons)
        self.laws = ActuatorLaws(actuators, order)
        self.paths = paths
        self.rows = np.array([paths.index(tendons[a]) for a in order], dtype=int)
        self.push = RootPush(paths.model, paths.mapping) if paths.floating else None  # a free joint's share
        self.implicit_kv = implicit_kv  # (damping, saturated) -> the kv MuJoCo's implicit step keeps
        self.damped = bool(self.laws.damping.any())

    applied = property(lambda self: self.push.applied if self.push is not None else ())  # root wrenches (momentum)

    def compile(self, layout) -> None:
        self.paths.compile(layout)

    def contribute(self, step: Step) -> None:
        laws = self.laws
        length, jacobian, v = self.paths.state(step)
        jacobian = jacobian[self.rows]
        unclamped = laws.unclamped(step.inputs[laws.indices], laws.gear * length[self.rows],
                                   laws.gear * (jacobian @ v))
        force = laws.clamped(unclamped)
        saturated = force != unclamped
        if saturated.any():
            step.regular = False
        implicit = None
        if self.damped and not step.explicit_kv:
            implicit = self.implicit_kv(laws.damping, saturated)  # gear^2 kv per actuator, none once clamped
        self.paths.apply(step, jacobian.T @ (laws.gear * force), self.push, jacobian, v, implicit)
