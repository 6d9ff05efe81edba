"""Passive spatial tendons: the spring (dead band between `lengthspring`'s ends) and damper of a tendon routed through
sites and wrapping geoms, f = -k (length - end) - b J qdot along the tendon's path (`tendon_paths.py`: MuJoCo's
length and Jacobian at SAPIEN's pose, the force as SAPIEN takes it). Euler takes the damper explicitly
(tests/test_loader_spatial_tendons.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from .dof_step import Step
from .integrated import RootPush
from .tendon_paths import TendonPaths, carried, is_spatial
from .tendons import COUPLED_DAMPING


class SpatialTendons:
    """The passive spatial tendons `tendons` (MuJoCo ids) along `paths`; `implicit`: MuJoCo's integrator holds
    dampers implicitly."""

    def __init__(self, paths: TendonPaths, tendons: list[int], implicit: bool):
        model = paths.model
        self.paths = paths
        self.rows = np.array([paths.index(t) for t in tendons], dtype=int)
        self.push = RootPush(model, paths.mapping) if paths.floating else None  # a free joint's share
        stiffness, damping = mj.tendon_passive(model)
        self.stiffness, self.damping = stiffness[tendons], damping[tendons]
        self.low, self.high = model.tendon_lengthspring[tendons].T.copy()
        self.implicit = implicit and bool(self.damping.any())  # the dampers' diagonal joins the drives

    applied = property(lambda self: self.push.applied if self.push is not None else ())  # root wrenches (momentum)

    def compile(self, layout) -> None:
        self.paths.compile(layout)

    def contribute(self, step: Step) -> None:
        length, jacobian, v = self.paths.state(step)
        length, jacobian = length[self.rows], jacobian[self.rows]
        stretch = np.where(length < self.low, length - self.low, np.where(length > self.high, length - self.high, 0.0))
        pull = -self.stiffness * stretch - self.damping * (jacobian @ v)
        implicit = self.damping if self.implicit and not step.explicit_kv else None
        self.paths.apply(step, jacobian.T @ pull, self.push, jacobian, v, implicit)

    def implicit_diagonal(self) -> dict[tuple[int, int], float]:
        """The dampers' diagonal b J_i^2 per DoF at qpos0 (what joins the drives under implicit integrators)."""
        return self.paths.implicit_diagonal(self.rows, self.damping) if self.implicit else {}


def plan_spatial(model: mujoco.MjModel, mapping: Mapping, notes, implicit: bool,
                 paths: TendonPaths | None) -> SpatialTendons | None:
    """The spatial tendons with a spring or damper along `paths` (those SAPIEN can carry: `tendon_paths.carried`;
    a tendon whose path crosses a ball joint is noted and left out)."""
    stiffness, damping = mj.tendon_passive(model)
    tendons = []
    for t in range(model.ntendon):
        if not is_spatial(model, t) or not (stiffness[t] or damping[t]):
            continue
        name = mj.name(model, "tendon", t)
        if not carried(model, mapping, t):
            notes.drop("tendon", name, "spatial tendon's spring and damper not mapped: the tendon moves a ball "
                       "joint, whose torque SAPIEN's joint forces do not take")
            continue
        if model.tendon_armature[t] > 0:
            notes.drop("tendon", name, f"tendon armature {model.tendon_armature[t]:g} not mapped")
        if implicit and damping[t] and len(mj.tendon_dofs(model, t)) > 1:
            notes.approximate("tendon", name, COUPLED_DAMPING)
        tendons.append(t)
    return SpatialTendons(paths, tendons, implicit) if tendons else None


def plan_paths(model: mujoco.MjModel, mapping: Mapping, actuated: list[int]) -> TendonPaths | None:
    """The paths of every spatial tendon SAPIEN can carry that has a spring or damper or drives an actuator
    (`actuated`, tendon ids), computed once per step for all of them."""
    stiffness, damping = mj.tendon_passive(model)
    tendons = [t for t in range(model.ntendon) if is_spatial(model, t) and carried(model, mapping, t) and (
        t in actuated or stiffness[t] or damping[t])]
    return TendonPaths(model, mapping, tendons) if tendons else None
