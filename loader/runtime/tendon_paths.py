"""Spatial tendons' paths at SAPIEN's pose: lengths and Jacobians from MuJoCo, and their forces applied as SAPIEN
takes them.

A spatial tendon's length and Jacobian J (over MuJoCo's DoFs) change with the pose, so MuJoCo computes them at
SAPIEN's state each step (`mj_kinematics`, `mj_comPos`, `mj_tendon` on a data of the loaded model), once per step for
every consumer (passive springs and dampers, tendon actuators). A generalized force J^T f over the tendons' DoFs is
joint forces on hinges and slides and, on a free joint (a tendon anchored off the floating tree), a wrench on the
root link (`RootPush`). MuJoCo's implicitfast holds a damper's or kv's whole J^T J implicitly; a drive holds one
DoF, so the diagonal joins the drives and the rest stays explicit (tests/test_loader_spatial_tendons.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from .dof_step import Step
from .integrated import RootPush
from .rows import scalar_state

CARRIED = ("hinge", "slide", "free")  # joints whose share of a tendon's force SAPIEN applies


def carried(model: mujoco.MjModel, mapping: Mapping, tendon: int) -> bool:
    """Whether SAPIEN can apply a force along the tendon: every DoF it moves is a mapped hinge, slide or free joint."""
    return all(mapping.joints[int(model.dof_jntid[d])].kind in CARRIED for d in mj.tendon_dofs(model, tendon))


def is_spatial(model: mujoco.MjModel, tendon: int) -> bool:
    return int(model.wrap_type[model.tendon_adr[tendon]]) != int(mujoco.mjtWrap.mjWRAP_JOINT)


class TendonPaths:
    """The spatial tendons `tendons` (MuJoCo ids) over the DoFs `dofs` (MuJoCo's) they move: the hinge and slide
    ones SAPIEN's `keys` (columns `joint`)."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, tendons: list[int]):
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.tendons = np.array(tendons, dtype=int)
        dofs = sorted(set().union(*(mj.tendon_dofs(model, t) for t in tendons)))
        self.dofs = np.array(dofs, dtype=int)
        targets = [mapping.joints[int(model.dof_jntid[d])] for d in dofs]
        self.joint = np.array([t.kind in ("hinge", "slide") for t in targets], dtype=bool)
        self.floating = not self.joint.all()  # a free joint among the DoFs
        self.keys = [(t.articulation, t.dofs[0]) for t, on in zip(targets, self.joint) if on]
        column = {d: i for i, d in enumerate(dofs)}  # MuJoCo keeps ten_J sparse, its pattern fixed by the model
        entries = [(k, column[int(model.ten_J_colind[a])], a) for k, t in enumerate(tendons) for a in range(
            int(model.ten_J_rowadr[t]), int(model.ten_J_rowadr[t] + model.ten_J_rownnz[t]))]
        self.row, self.column, self.entry = (np.array(x, dtype=int) for x in zip(*entries))
        self.last: tuple | None = None  # (step, its state): one pass per step for every consumer

    def index(self, tendon: int) -> int:
        return int(np.flatnonzero(self.tendons == tendon)[0])

    def compile(self, layout) -> None:
        self.flat = layout.flat_of(self.keys)
        self.drive = layout.drive_of(self.keys)
        self.scalar = scalar_state(self.model, self.mapping, layout)
        self.last = None

    def state(self, step: Step) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tendons' lengths, Jacobian (tendon x `dofs`) and the DoFs' velocities at the step's start."""
        if self.last is not None and self.last[0] is step:
            return self.last[1]
        if self.scalar is not None:  # hinges and slides only
            qpos, v = step.q[self.scalar], step.v[self.flat]
        else:
            qpos, qvel = step.mujoco_state(self.mapping)
            v = qvel[self.dofs]
        found = (*self.measure(qpos), v)
        self.last = (step, found)
        return found

    def measure(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tendons' lengths and Jacobian (tendon x `dofs`) at MuJoCo's `qpos`."""
        model, data = self.model, self.data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        return data.ten_length[self.tendons], self.dense(data)

    def dense(self, data: mujoco.MjData) -> np.ndarray:
        """The tendons' rows of MuJoCo's sparse ten_J, over `dofs`."""
        jacobian = np.zeros((len(self.tendons), len(self.dofs)))
        jacobian[self.row, self.column] = data.ten_J[self.entry]
        return jacobian

    def apply(self, step: Step, force: np.ndarray, push: RootPush | None, jacobian: np.ndarray, v: np.ndarray,
              implicit: np.ndarray | None = None) -> None:
        """A generalized force over `dofs` into the step: joint forces, a free joint's share through `push` (once
        per physics step); `implicit`: per tendon of `jacobian`'s rows, the damping whose diagonal d J_i^2 the
        drives take implicitly (and the explicit force gives back at the current rate)."""
        if push is not None:
            if step.advance:
                whole = np.zeros(self.model.nv)
                whole[self.dofs] = force
                push(self.data, whole, step.layout.links)
            force, jacobian, v = force[self.joint], jacobian[:, self.joint], v[self.joint]
        if implicit is not None:
            diagonal = implicit @ (jacobian * jacobian)
            force = force + diagonal * v
            np.add.at(step.law[5], self.drive, diagonal)
            step.regular = False  # the implicit extra changes with the pose
        np.add.at(step.force, self.flat, force)

    def implicit_diagonal(self, rows: np.ndarray, damping: np.ndarray) -> dict[tuple[int, int], float]:
        """d J_i^2 per DoF at qpos0 over the tendons `rows` (what joins the drives under implicit integrators)."""
        jacobian = self.dense(mj.forward_at(self.model))[np.ix_(rows, self.joint)]
        return dict(zip(self.keys, (damping @ (jacobian * jacobian)).tolist()))
