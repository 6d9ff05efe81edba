"""Passive spatial tendons: the spring (dead band between `lengthspring`'s ends) and damper of a tendon routed through
sites and wrapping geoms, applied as joint forces J^T f (a free joint's share as a wrench on its root link).

A spatial tendon's length and Jacobian J (over MuJoCo's DoFs) change with the pose, so MuJoCo computes them at
SAPIEN's state each step (`mj_kinematics`, `mj_comPos`, `mj_tendon` on a data of the loaded model) and the force
is MuJoCo's: f = -k (length - end) - b J qdot. Euler takes the damper explicitly, as here. MuJoCo's implicit
integrators hold the whole b J^T J implicitly; a drive holds one DoF, so its diagonal b J_i^2 joins the drives and
the rest stays explicit (an approximation note names such tendons)
(tests/test_loader_spatial_tendons.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from .dof_step import Step
from .integrated import RootPush
from .rows import scalar_state
from .tendons import COUPLED_DAMPING

CARRIED = ("hinge", "slide", "free")  # joints whose share of a tendon's force SAPIEN applies


class SpatialTendons:
    """The passive spatial tendons `tendons` (MuJoCo ids) over the DoFs `dofs` (MuJoCo's) they move: the hinge and
    slide ones SAPIEN's `keys` (columns `joint`), a free joint's as a wrench on its root link (`RootPush`);
    `implicit`: MuJoCo's integrator holds dampers implicitly."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, tendons: list[int], dofs: list[int], implicit: bool):
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.tendons = np.array(tendons, dtype=int)
        self.dofs = np.array(dofs, dtype=int)
        targets = [mapping.joints[int(model.dof_jntid[d])] for d in dofs]
        self.joint = np.array([t.kind in ("hinge", "slide") for t in targets], dtype=bool)
        self.keys = [(t.articulation, t.dofs[0]) for t, on in zip(targets, self.joint) if on]
        self.push = RootPush(model, mapping) if not self.joint.all() else None  # a free joint's share
        spring, damper = not mj.disabled(model, "spring"), not mj.disabled(model, "damper")
        self.stiffness = model.tendon_stiffness[self.tendons] * spring
        self.damping = model.tendon_damping[self.tendons] * damper
        self.low, self.high = model.tendon_lengthspring[self.tendons].T.copy()
        self.implicit = implicit and bool(self.damping.any())  # the dampers' diagonal joins the drives
        column = {d: i for i, d in enumerate(dofs)}  # MuJoCo keeps ten_J sparse, its pattern fixed by the model
        entries = [(k, column[int(model.ten_J_colind[a])], a) for k, t in enumerate(tendons) for a in range(
            int(model.ten_J_rowadr[t]), int(model.ten_J_rowadr[t] + model.ten_J_rownnz[t]))]
        self.row, self.column, self.entry = (np.array(x, dtype=int) for x in zip(*entries))

    applied = property(lambda self: self.push.applied if self.push is not None else ())  # root wrenches (momentum)

    def compile(self, layout) -> None:
        self.flat = layout.flat_of(self.keys)
        self.drive = layout.drive_of(self.keys)
        self.scalar = scalar_state(self.model, self.mapping, layout)

    def state(self, step: Step) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tendons' lengths, Jacobian (tendon x `dofs`) and the DoFs' velocities at the step's start."""
        model, data = self.model, self.data
        if self.scalar is not None:  # hinges and slides only
            data.qpos[:], v = step.q[self.scalar], step.v[self.flat]
        else:
            qpos, qvel = step.mujoco_state(self.mapping)
            data.qpos[:], v = qpos, qvel[self.dofs]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        return data.ten_length[self.tendons], self.dense(data), v

    def dense(self, data: mujoco.MjData) -> np.ndarray:
        """The tendons' rows of MuJoCo's sparse ten_J, over `dofs`."""
        jacobian = np.zeros((len(self.tendons), len(self.dofs)))
        jacobian[self.row, self.column] = data.ten_J[self.entry]
        return jacobian

    def contribute(self, step: Step) -> None:
        length, jacobian, v = self.state(step)
        stretch = np.where(length < self.low, length - self.low, np.where(length > self.high, length - self.high, 0.0))
        pull = -self.stiffness * stretch - self.damping * (jacobian @ v)
        force = jacobian.T @ pull
        if self.push is not None:
            if step.advance:
                whole = np.zeros(self.model.nv)
                whole[self.dofs] = force
                self.push(self.data, whole, step.layout.links)
            force, jacobian, v = force[self.joint], jacobian[:, self.joint], v[self.joint]
        if self.implicit and not step.explicit_kv:
            diagonal = self.damping @ (jacobian * jacobian)  # b J_i^2 per DoF: the drive takes it implicitly
            force += diagonal * v
            np.add.at(step.law[5], self.drive, diagonal)
            step.regular = False  # the implicit extra changes with the pose
        np.add.at(step.force, self.flat, force)

    def implicit_diagonal(self) -> dict[tuple[int, int], float]:
        """The dampers' diagonal b J_i^2 per DoF at qpos0 (what joins the drives under implicit integrators)."""
        if not self.implicit:
            return {}
        jacobian = self.dense(mj.forward_at(self.model))[:, self.joint]
        return dict(zip(self.keys, (self.damping @ (jacobian * jacobian)).tolist()))


def plan_spatial(model: mujoco.MjModel, mapping: Mapping, notes, implicit: bool) -> SpatialTendons | None:
    """The spatial tendons with a spring or damper whose every DoF is a mapped hinge, slide or free joint (a tendon
    moving a ball joint is noted and left out: its force would be a ball joint torque)."""
    spring, damper = not mj.disabled(model, "spring"), not mj.disabled(model, "damper")
    tendons, dofs = [], set()
    for t in range(model.ntendon):
        if int(model.wrap_type[model.tendon_adr[t]]) == int(mujoco.mjtWrap.mjWRAP_JOINT):
            continue  # a fixed tendon (`tendons.py`)
        if not ((spring and model.tendon_stiffness[t]) or (damper and model.tendon_damping[t])):
            continue
        name, moved = mj.name(model, "tendon", t), tendon_columns(model, t)
        if not all(mapping.joints[int(model.dof_jntid[d])].kind in CARRIED for d in moved):
            notes.drop("tendon", name, "spatial tendon's spring and damper not mapped: the tendon moves a ball "
                       "joint, whose torque SAPIEN's joint forces do not take")
            continue
        if model.tendon_armature[t] > 0:
            notes.drop("tendon", name, f"tendon armature {model.tendon_armature[t]:g} not mapped")
        if implicit and model.tendon_damping[t] and damper and len(moved) > 1:
            notes.approximate("tendon", name, COUPLED_DAMPING)
        tendons.append(t)
        dofs |= moved
    return SpatialTendons(model, mapping, tendons, sorted(dofs), implicit) if tendons else None


def tendon_columns(model: mujoco.MjModel, tendon: int) -> set[int]:
    """The DoFs of a tendon's row of MuJoCo's sparse Jacobian (those its length can depend on)."""
    start = int(model.ten_J_rowadr[tendon])
    return {int(d) for d in model.ten_J_colind[start:start + int(model.ten_J_rownnz[tendon])]}
