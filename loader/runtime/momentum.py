"""A floating robot's root velocity after a PhysX step, in MuJoCo's convention.

Both simulators give the joints the same velocities over a step; they differ in what the floating root keeps.
PhysX's articulation step conserves momentum: the linear momentum ends at P(q0, v0) + dt F (F: gravity and the
link forces), and the angular momentum about the centre of mass keeps the size of L(q0, v0) + dt T (T: their
torque about it) while taking its direction from an uncorrected intermediate. MuJoCo's semi-implicit Euler keeps
qvel: its momentum ends at A(q0) v1 = (P, L)(q0, v0) + dt (F, T) - dt (dA/dt) v0, A the centroidal momentum
matrix. Where the links turn relative to each other within a step, the roots end with different velocities.

`Momentum.settle` recovers MuJoCo's root velocity after a physics step: it solves
A(q0) v1 = (P', L) - dt (dA/dt) v0 for the root's part of v1, with P' PhysX's end linear momentum, L the start's
angular momentum plus dt T scaled to PhysX's end size, and the joint part PhysX's; it writes the root pose MuJoCo's
position update gives. Contact torques, which it cannot see, leave L's size right and its direction approximate.
It acts only where the joints moved exactly as PhysX's position update moves them (position by timestep x
velocity): not after a `set_state`, where contacts corrected positions, or on a second read.
(tests/test_loader_momentum.py::test_a_free_robot_kicked_by_its_joints_keeps_mujocos_root_velocity)
"""

from __future__ import annotations

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from ..frames import cross3, quat_to_mat

FREE = int(mujoco.mjtJoint.mjJNT_FREE)
DRIFT_STEP = 1e-6  # rad or m moved along v for the forward difference of A
MOVED = 1e-6  # joint positions (rad, m) agree with timestep x velocity to float32 rounding (plus this, relative)


def composite(data: mujoco.MjData, bodies: np.ndarray) -> tuple[float, np.ndarray]:
    """Mass and rotational inertia about its centre of mass (world axes) of a tree, from `cinert` (MuJoCo's
    per-body inertia about the tree's centre of mass)."""
    total = data.cinert[bodies].sum(axis=0)
    xx, yy, zz, xy, xz, yz = total[:6]
    return float(total[9]), np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def pose7(art) -> np.ndarray:
    pose = art.get_root_pose()
    return np.concatenate([pose.p, pose.q])


def advanced(qpos7: np.ndarray, qvel6: np.ndarray, dt: float) -> np.ndarray:
    """A free joint's position after MuJoCo's position update: origin by dt times its velocity, orientation turned
    by dt times the body-frame angular velocity."""
    quat = np.array(qpos7[3:], np.float64)
    mujoco.mju_quatIntegrate(quat, qvel6[3:], dt)
    return np.concatenate([qpos7[:3] + dt * qvel6[:3], quat])


def angular(kept: np.ndarray, carried: np.ndarray) -> np.ndarray:
    """The angular momentum the step carried: PhysX keeps its size and loses its direction (it rescales an
    uncorrected intermediate's); `carried` is the start's plus dt times the known external torque (contacts'
    torques, unknown here, change only the direction)."""
    size, norm = float(np.linalg.norm(kept)), float(np.linalg.norm(carried))
    return carried * (size / norm) if norm > 0.0 else kept


class Momentum:
    """Per floating articulation with joints: its root body, free joint's addresses and tree's bodies."""

    name = "momentum"

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, roots: list[tuple[int, int, int, int, np.ndarray]],
                 timestep: float):
        self.model, self.mapping, self.roots = model, mapping, roots  # (articulation, body, qposadr, dofadr, tree)
        self.data = mujoco.MjData(model)
        self.timestep = timestep
        self.start: tuple | None = None  # at the last set_ctrl: MuJoCo's qpos and qvel, SAPIEN's joint positions
        self.gravity = np.zeros(3) if mj.disabled(model, "gravity") else np.array(model.opt.gravity, np.float64)
        # per root: the mass gravity pulls on, per body of its tree (none of a compensated body's)
        self.weights = [model.body_mass[tree] * (1.0 - model.body_gravcomp[tree]) for *_, tree in roots]

    def contribute(self, step) -> None:
        """Remember the state this physics step starts from (`set_ctrl` settles the last step before)."""
        q = step.layout.split(step.q)
        qpos, qvel = step.mujoco_state(self.mapping)
        poses = [pose7(step.articulations[a]) for a, *_ in self.roots]
        self.start = (qpos, qvel, [q[a].copy() for a, *_ in self.roots], poses)

    def forget(self, joints=None) -> None:
        """The state was set from outside (or the term switched off): the next read is not the end of a step."""
        self.start = None

    removed = forget

    def settle(self, articulations, wrenches=()) -> None:
        """Once after a physics step: each floating root's velocity as MuJoCo's step leaves it. `wrenches`: the
        link forces the loader added this step, (articulation, point, force, torque) in the world."""
        if self.start is None:
            return
        qpos0, qvel0, joints0, poses0 = self.start
        dt = self.timestep
        q = [np.asarray(art.get_qpos(), np.float64) for art in articulations]
        v = [np.asarray(art.get_qvel(), np.float64) for art in articulations]
        stepped, still = [], True
        for (a, *_), q0, pose0 in zip(self.roots, joints0, poses0):
            still = still and np.array_equal(q[a], q0) and np.array_equal(pose7(articulations[a]), pose0)
            if np.abs(q[a] - q0 - dt * v[a]).max(initial=0.0) <= MOVED * (1.0 + np.abs(q[a]).max(initial=0.0)):
                stepped.append(a)
        if still:
            return  # read before the physics step: it is still to come
        self.start = None
        if not stepped:
            return
        qpos1, qvel1 = self.mapping.get_state(articulations, q, v)
        kept, = self._momenta(qpos1, qvel1)  # what PhysX kept, at the step's end
        joints_only = qvel1.copy()
        for _, _, _, dof, _ in self.roots:
            joints_only[dof:dof + 6] = 0.0
        ahead, eps = self._ahead(qpos0, qvel0)
        started, joints_part = self._momenta(qpos0, qvel0, joints_only)  # at the step's start (data stays there)
        for (a, body, qadr, dof, tree), weights, k, s0, ah, j in zip(self.roots, self.weights, kept, started, ahead,
                                                                      joints_part):
            if a not in stepped:
                continue
            drift = (ah - s0) / eps  # (dA/dt) v0, a forward difference along v0
            carried = s0[3:] + dt * self._torque(a, body, tree, weights, wrenches)
            k = np.concatenate([k[:3], angular(k[3:], carried)])
            mass, inertia = composite(self.data, tree)
            offset = self.data.subtree_com[body] - qpos0[qadr:qadr + 3]  # centre of mass from the root's origin
            root = k - dt * drift - j  # the root's own momentum at q0
            omega = np.linalg.solve(inertia, root[3:])
            linear = root[:3] / mass - cross3(omega, offset)
            qvel6 = np.concatenate([linear, quat_to_mat(qpos0[qadr + 3:qadr + 7]).T @ omega])
            self.mapping.set_root(articulations[a], body, advanced(qpos0[qadr:qadr + 7], qvel6, dt), qvel6)
            articulations[a].set_qvel(articulations[a].get_qvel())  # its links' velocities follow the root's

    def _torque(self, art: int, body: int, tree: np.ndarray, weights: np.ndarray, wrenches) -> np.ndarray:
        """External torque about the tree's centre of mass at the step's start (`self.data` there): gravity on
        the links it acts on (`weights`) and the loader's link forces."""
        centre = self.data.subtree_com[body]
        torque = cross3(weights @ self.data.xipos[tree] - weights.sum() * centre, self.gravity)
        for a, point, force, moment in wrenches:
            if a == art:
                torque += moment + cross3(point - centre, force)
        return torque

    def _ahead(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[list[np.ndarray], float]:
        """Per root, the momentum A(q + e v) v a small step e along v; and e (for the forward difference)."""
        eps = DRIFT_STEP / max(1.0, float(np.abs(qvel).max(initial=0.0)))
        ahead = np.array(qpos)
        mujoco.mj_integratePos(self.model, ahead, qvel, eps)
        momenta, = self._momenta(ahead, qvel)
        return momenta, eps

    def _momenta(self, qpos: np.ndarray, *velocities: np.ndarray) -> list[list[np.ndarray]]:
        """Per velocity, per root: the tree's linear momentum and angular momentum about its centre of mass at
        qpos, as one 6-vector; leaves `self.data` at that pose (its `cinert` and `subtree_com` serve the composite
        inertia)."""
        model, data = self.model, self.data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        out = []
        for qvel in velocities:
            data.qvel[:] = qvel
            mujoco.mj_comVel(model, data)
            mujoco.mj_subtreeVel(model, data)
            out.append([np.concatenate([data.subtree_linvel[body] * model.body_subtreemass[body],
                                        data.subtree_angmom[body]]) for _, body, *_ in self.roots])
        return out


def plan_momentum(model: mujoco.MjModel, mapping: Mapping, articulations: list, timestep: float) -> Momentum | None:
    """The floating articulations with joints (None without any): those whose root body has MuJoCo's free joint."""
    roots = []
    for j, target in enumerate(mapping.joints):
        if int(model.jnt_type[j]) != FREE or articulations[target.articulation].dof == 0:
            continue
        body = int(model.jnt_bodyid[j])
        tree = np.flatnonzero(model.body_rootid == body)
        roots.append((target.articulation, body, int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]), tree))
    return Momentum(model, mapping, roots, timestep) if roots else None
