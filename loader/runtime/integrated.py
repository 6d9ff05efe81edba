"""The constraint force MuJoCo's step integrates, from a solve of MuJoCo's copy (`rows.py`).

Its implicit integrators, and Euler with implicit damping, solve for the acceleration from `qfrc_constraint`. Euler
without implicit damping (and RK4, simulated as Euler) integrates the solver's own qacc, which a solver stopped before
convergence (`iterations="1"`) leaves short of `qfrc_constraint`'s: there the force is M (qacc - qacc_smooth) less
the contact rows' J^T f, and it can push a free joint, whose share goes on the root link as a wrench.
(tests/test_loader_unconverged.py)
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from ..model.frames import cross, quat_to_mat
from ..model.joints import FREE
from ..model.mapping import Mapping


def accelerated(model: mujoco.MjModel) -> bool:
    """Whether MuJoCo's step integrates the solver's qacc (not an acceleration solved from the forces)."""
    euler = int(model.opt.integrator) in mj.EULER_LIKE
    return euler and (mj.explicit_damping(model) or not np.any(model.dof_damping))


def integrated_force(model: mujoco.MjModel, data: mujoco.MjData, rows: np.ndarray | None, qacc: bool) -> np.ndarray:
    """The generalized force of the constraint rows `rows` (a mask over data's rows; None: all) that MuJoCo's step
    integrates (`qacc`: it integrates the solver's qacc). The other rows are contacts, solved with them while SAPIEN
    has contacts, which PhysX applies."""
    if not data.nefc:
        return np.zeros(model.nv)
    whole = rows is None or bool(rows.all())
    if not qacc and whole:
        return data.qfrc_constraint
    force = np.zeros(model.nv)
    if not qacc:
        if rows.any():
            mujoco.mj_mulJacTVec(model, data, force, np.where(rows, data.efc_force[: data.nefc], 0.0))
        return force
    mujoco.mj_mulM(model, data, force, data.qacc - data.qacc_smooth)
    if not whole:
        pushed = np.zeros(model.nv)
        mujoco.mj_mulJacTVec(model, data, pushed, np.where(rows, 0.0, data.efc_force[: data.nefc]))
        force -= pushed
    return force


class RootPush:
    """A constraint force's share on the floating roots, as a wrench on each root link (added once per physics
    step): a weld or connect holding a floating body, or an unconverged solve."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping):
        self.roots = []  # (articulation, link, body, dof address, centre of mass in the body frame)
        for j, target in enumerate(mapping.joints):
            if int(model.jnt_type[j]) == FREE:
                body = int(model.jnt_bodyid[j])
                self.roots.append(
                    (
                        target.articulation,
                        mapping.bodies[body].link,
                        body,
                        int(model.jnt_dofadr[j]),
                        mapping.centres[body],
                    )
                )
        self.applied: list = []  # this step's wrenches (articulation, centre of mass, force, torque), world

    def __call__(self, data: mujoco.MjData, force: np.ndarray, links: list) -> None:
        """`data` at the step's start; `links` per articulation."""
        self.applied.clear()
        for art, link, body, dof, centre in self.roots:
            if force[dof : dof + 6].any():
                self.add(
                    links[art][link], art, data.xmat[body].reshape(3, 3), data.xpos[body], centre, force[dof : dof + 6]
                )

    def at_roots(self, force: np.ndarray, articulations: list, links: list) -> None:
        """The same, the roots' frames read from SAPIEN's root poses: a caller's `qfrc_applied`."""
        self.applied.clear()
        for art, link, _, dof, centre in self.roots:
            if force[dof : dof + 6].any():
                pose = articulations[art].get_root_pose()
                origin = np.asarray(pose.p, np.float64)
                self.add(links[art][link], art, quat_to_mat(pose.q), origin, centre, force[dof : dof + 6])

    def add(self, link, art: int, rotation: np.ndarray, origin: np.ndarray, centre: np.ndarray, wrench) -> None:
        """A free joint's generalized force (a world force at the body's origin, a torque in its frame) as a force
        and torque at the link's centre of mass."""
        com = origin + rotation @ centre
        torque = rotation @ wrench[3:] + cross(origin - com, wrench[:3])
        link.add_force_torque(wrench[:3].astype(np.float32), torque.astype(np.float32))
        self.applied.append((art, com, np.array(wrench[:3], np.float64), torque))
