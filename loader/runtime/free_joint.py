"""What MuJoCo's step does to a free joint that PhysX's step does not: the joint's damping and armature, and,
under the implicit integrators, a lone free body's gyroscopic term taken implicitly.

MuJoCo's step is (M - dt Q)(v1 - v0) = dt f(v0): M its mass matrix at the step's start (armature inside), f every
force, Q the velocity derivative its integrator takes implicitly: minus the damping (Euler with `eulerdamp`,
implicit, implicitfast), plus, for a tree of one body under implicit or implicitfast, the derivative J of the
body's gyroscopic force (MuJoCo 3.17 takes it for such a tree only; articulated trees under implicitfast get none).
PhysX with the loader's other terms ends the step at v' with (M - A + dt D_j)(v' - v0) = dt (f(v0) + B v0): no
free joint armature A or damping B, the tree's other damping D_j as the drives carry it. So MuJoCo's end is
v1 = v0 + (M - dt Q)^-1 ((M - A + dt D_j)(v' - v0) - dt B v0). The tree's hinges and slides take their part of
it; ball joints keep PhysX's. (tests/test_loader_free_joint.py)
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from ..model.frames import quat_to_mat
from ..model.mapping import Mapping, scalar_joints
from ..model.options import IMPLICIT


def differs(model: mujoco.MjModel, joint: int, tree: np.ndarray) -> bool:
    """Whether MuJoCo's step adds to free joint `joint` (of `tree`'s root) what PhysX's does not."""
    dof = int(model.jnt_dofadr[joint])
    own = model.dof_damping[dof : dof + 6].any() or model.dof_armature[dof : dof + 6].any()
    return bool(own or (tree.size == 1 and int(model.opt.integrator) in IMPLICIT))


def skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def gyroscopic_derivative(
    mass: float, com: np.ndarray, rotation: np.ndarray, inertia: np.ndarray, omega: np.ndarray
) -> np.ndarray:
    """d f / d v of a lone free body's velocity-dependent force, in MuJoCo's free joint coordinates (the origin's
    velocity in the world, the body-frame angular velocity omega): f = -(m R (w x (w x c)), w x I_o w), c the centre
    of mass and I_o the inertia about the origin, both in the body frame. It does not depend on the linear part."""
    derivative = np.zeros((6, 6))
    arm = np.outer(omega, com) + (omega @ com) * np.eye(3) - 2.0 * np.outer(com, omega)  # d(w x (w x c))/dw
    derivative[:3, 3:] = -mass * rotation @ arm
    derivative[3:, 3:] = skew(inertia @ omega) - skew(omega) @ inertia
    return derivative


class FreeJointLaw:
    """Per root whose free joint `differs`: its tree's DoFs, the free joint's armature and damping on them (zeros
    elsewhere), and the damping MuJoCo takes implicitly; applied after each step by `Momentum.settle`."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, roots: list, timestep: float):
        self.model, self.timestep = model, timestep
        self.damping = model.dof_damping * (not mj.explicit_damping(model))  # MuJoCo's implicit damping D, per DoF
        self.gyroscopic = int(model.opt.integrator) in IMPLICIT
        self.dense = np.zeros((model.nv, model.nv))
        self.centres = mapping.centres
        self.scalars = {a: (dofadr, dofs) for a, _, dofadr, dofs in scalar_joints(mapping)}
        self.roots = {root.articulation: self._plan(root) for root in roots}

    def _plan(self, root) -> tuple:
        """Per root, what its step reuses: the tree's block of the mass matrix (`np.ix_`), dt D (added to it on the
        left), -A + dt D_j (on the right), the free joint's damping B and rotational armature, and where the tree's
        hinges and slides sit among its DoFs."""
        model, dofs, dt = self.model, root.dofs, self.timestep
        own = (dofs >= root.dofadr) & (dofs < root.dofadr + 6)
        armature = np.where(own, model.dof_armature[dofs], 0.0)
        joints = np.where(own, 0.0, self.damping[dofs])
        scalars = self.scalars.get(root.articulation)
        where = np.searchsorted(dofs, scalars[0]) if scalars is not None else None
        return (
            np.ix_(dofs, dofs),
            dt * np.diag(self.damping[dofs]),
            np.diag(dt * joints - armature),
            np.where(own, model.dof_damping[dofs], 0.0),
            np.diag(armature[3:6]),
            where,
        )

    def correct(self, data: mujoco.MjData, roots: list, qvel0: np.ndarray, qvel1: np.ndarray, articulations) -> None:
        """Turn `qvel1` (PhysX's end, MuJoCo's layout) into MuJoCo's on each of `roots`' trees, from `data` at the
        step's start; write the trees' hinge and slide velocities into PhysX (the roots' are the caller's)."""
        if not roots:
            return
        model, dt = self.model, self.timestep
        mujoco.mj_crb(model, data)  # the mass matrix at q0 (kinematics and centre-of-mass positions are there)
        mujoco.mj_fullM(model, data, self.dense)
        for root in roots:
            block, implicit, shift, damping, rotational, where = self.roots[root.articulation]
            dofs = root.dofs
            mass = self.dense[block]
            lhs = mass + implicit
            if self.gyroscopic and root.tree.size == 1:
                body = root.body
                inertia = mass[3:, 3:] - rotational  # about the origin, in the body frame
                rotation = quat_to_mat(data.xquat[body])
                omega = qvel0[root.dofadr + 3 : root.dofadr + 6]
                lhs[:6, :6] -= dt * gyroscopic_derivative(
                    float(model.body_mass[body]), self.centres[body], rotation, inertia, omega
                )
            start, physx = qvel0[dofs], qvel1[dofs]
            rhs = (mass + shift) @ (physx - start) - dt * damping * start
            end = start + np.linalg.solve(lhs, rhs)
            qvel1[dofs] = end
            if where is not None:  # PhysX moved the tree's hinges and slides by dt times its velocity
                self._joints(articulations[root.articulation], root.articulation, end[where] - physx[where], qvel1)

    def _joints(self, art, index: int, change: np.ndarray, qvel1: np.ndarray) -> None:
        """The articulation's hinges and slides at MuJoCo's end velocity, moved as MuJoCo's position update
        moves them (PhysX's by dt times its own; `change`: MuJoCo's velocity less PhysX's)."""
        dofadr, sapien = self.scalars[index]
        q, v = (np.asarray(x, np.float64) for x in (art.get_qpos(), art.get_qvel()))
        q[sapien] += self.timestep * change
        v[sapien] = qvel1[dofadr]
        art.set_qpos(q.astype(np.float32))
        art.set_qvel(v.astype(np.float32))
