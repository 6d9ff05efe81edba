"""A floating tree's centroidal momentum and composite inertia from MuJoCo's kinematic passes, for `momentum.py`.

`Passes` runs them on one MjData for one copy of a model, or for the copies a `Batch` drives at once: `stack` builds
one model that holds every copy's bodies and joints (each copy's bodies, joints and DoFs in a block of their own,
every number copied from the compiled model), so one kinematics, centre-of-mass, velocity and RNE pass serves
them all, and each copy gets the numbers its own model would give, bit for bit; `stack` checks that on a random
state before it is used (tests/test_loader_batch.py::test_a_stack_of_copies_gives_each_copy_its_own_numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..model.joints import BALL, FREE

ZERO = np.zeros(3)  # no torque (`mj_applyFT` only reads it)
BODY_NUMBERS = ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass", "body_inertia", "body_subtreemass")
BODY_FLAGS = ("body_sameframe", "body_simple")
CHECKED = ("xipos", "cinert", "subtree_com", "subtree_linvel", "subtree_angmom", "cfrc_int")  # what the settle reads


@dataclass(frozen=True)
class Start:
    """A tree at the step's start as the settle reads it: its centre of mass, mass, rotational inertia about the
    centre (world axes; xx, yy, zz, xy, xz, yz), and the sum of weight x position over its links."""

    centre: list[float]
    mass: float
    inertia: tuple
    moment: list[float]


@dataclass(frozen=True)
class Momenta:
    """Per root of one copy, as six floats (linear momentum, angular momentum about the tree's centre of mass):
    PhysX's at the step's end (`kept`), the start's (`started`), the start's of the joints' velocities alone
    (`joints_part`) and the drift (dA/dt) v0 (`drifts`); and the trees at the start (`starts`)."""

    kept: list[list[float]]
    started: list[list[float]]
    joints_part: list[list[float]]
    drifts: list[list[float]]
    starts: list[Start]


@dataclass(frozen=True)
class Ended:
    """One copy's physics step as the settle reads it back: MuJoCo's state at its start (`qpos0`, `qvel0`) and
    PhysX's at its end (`qpos1`, `qvel1`; the roots' part read only where a root is not `balanced`), that velocity
    with the roots' part zeroed (`joints_only`), the roots that stepped, SAPIEN's contacts of the step and the
    roots that stepped whose free joint's rows give their velocity (`Passes.root_rows`)."""

    qpos0: np.ndarray
    qvel0: np.ndarray
    qpos1: np.ndarray
    qvel1: np.ndarray
    joints_only: np.ndarray
    stepped: list
    contacts: list
    balanced: list = ()

    @property
    def unbalanced(self) -> bool:
        """Whether a root that stepped needs the momenta (`Passes.momenta`)."""
        return len(self.balanced) < len(self.stepped)


class Passes:
    """MuJoCo's passes on `data` (of `model`, which holds `copies` copies of `single`, `stack`) for the floating
    `roots` of one copy: their bodies and trees offset per copy."""

    def __init__(
        self, model: mujoco.MjModel, single: mujoco.MjModel, roots: list, gravity: np.ndarray, copies: int = 1
    ):
        self.model, self.data, self.copies = model, mujoco.MjData(model), copies
        self.single, self.roots = single, roots
        stride = single.nbody - 1  # the world is shared
        shifts = [k * stride for k in range(copies)]
        self.bodies = np.array([root.body + s for s in shifts for root in roots], dtype=int)
        self.trees = [root.tree + s for s in shifts for root in roots]
        self.weights = [root.weights for _ in shifts for root in roots]
        self.masses = np.array([single.body_subtreemass[root.body] for _ in shifts for root in roots])[:, None]
        self.rates_weight = self.masses * gravity  # per root, the weight its cfrc_int carries beside the drift
        self.stride = stride
        nv = model.nv  # the root rows' arrays (`root_rows`)
        self.bias, self.pushed, self.change, self.coupled = (np.zeros(nv) for _ in range(4))
        self.dense = np.zeros((single.nv, single.nv)) if copies == 1 else None
        self.columns, self.unit = np.zeros((6, nv)), np.zeros(nv)
        self.block, self.solution = np.zeros((6, 6)), np.zeros(6)

    def root_rows(self, ended: list[Ended | None], wrenches: list[list], timestep: float) -> None:
        """Per copy (None: no root of it is `balanced`), its balanced roots' velocities in its `qvel1` from MuJoCo's
        step on their free joints' rows at the step's start, the joints' part PhysX's:

            M_rr (v1_r - v0_r) = dt (tau_r - c_r) - M_rj (v1_j - v0_j),

        c MuJoCo's bias (gravity on every body), tau the link forces the loader added (`wrenches`, per copy) and the
        lift of the compensated bodies, each as J^T f at the root (the tree's other rows are PhysX's); solved as
        M_rr v1_r = dt (tau_r - c_r) - (M u)_r, u the joints' change with -v0 on the roots. One pass of MuJoCo's
        kinematics, mass matrix and bias serves every copy; `data` is left at the starts
        (tests/test_loader_momentum.py::test_the_root_rows_are_mujocos_step)."""
        model, data, bias, pushed = self.model, self.data, self.bias, self.pushed
        data.qpos[:] = self._joined([e.qpos0 if e else None for e in ended], self.single.qpos0)
        data.qvel[:] = self._joined([e.qvel0 if e else None for e in ended], np.zeros(self.single.nv))
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_crb(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_rne(model, data, 0, bias)
        if self._push(ended, wrenches):
            bias -= pushed
        self.change[:] = self._joined([e.joints_only - e.qvel0 if e else None for e in ended], np.zeros(self.single.nv))
        mujoco.mj_mulM(model, data, self.coupled, self.change)
        blocks = self._root_blocks(ended)
        nv, block, solution = self.single.nv, self.block, self.solution
        for k, e in enumerate(ended):
            for root in e.balanced if e else ():
                rows = slice(root.dofadr + k * nv, root.dofadr + k * nv + 6)
                block[:] = blocks(rows)
                mujoco.mju_cholFactor(block, 0.0)  # numpy's solve of a 6 x 6 costs several times MuJoCo's
                mujoco.mju_cholSolve(solution, block, -timestep * bias[rows] - self.coupled[rows])
                e.qvel1[root.dofadr : root.dofadr + 6] = solution

    def _push(self, ended: list[Ended | None], wrenches: list[list]) -> bool:
        """The balanced trees' link forces and lifts as J^T f into `pushed`; False where there is none."""
        model, data, pushed = self.model, self.data, self.pushed
        acting = []
        for k, (e, copy) in enumerate(zip(ended, wrenches)):
            if e is None:
                continue
            shift = k * self.stride
            bodies = {root.articulation: root.body + shift for root in e.balanced}
            for root in e.balanced:
                for body, lift in root.lifted:
                    acting.append((lift, ZERO, data.xipos[body + shift], root.body + shift))
            acting += [(force, moment, point, bodies[a]) for a, point, force, moment in copy if a in bodies]
        if not acting:
            return False
        pushed[:] = 0.0
        for force, moment, point, body in acting:
            mujoco.mj_applyFT(model, data, force, moment, point, body, pushed)
        return True

    def _root_blocks(self, ended: list[Ended | None]):
        """A function of a root's rows giving its 6 x 6 block of M: from the dense M of one copy, or, on a stack
        (whose dense M grows with the square of its copies), from M times the roots' unit vectors, one per column:
        the same numbers, each a product by 1."""
        model, data = self.model, self.data
        if self.dense is not None:
            mujoco.mj_fullM(model, data, self.dense)
            return lambda rows: self.dense[rows, rows]
        nv = self.single.nv
        starts = np.array([r.dofadr + k * nv for k, e in enumerate(ended) for r in (e.balanced if e else ())], int)
        for i, column in enumerate(self.columns):
            self.unit[:] = 0.0
            self.unit[starts + i] = 1.0
            mujoco.mj_mulM(model, data, column, self.unit)
        return lambda rows: self.columns[:, rows]

    def momenta(self, ended: list[Ended | None]) -> list[Momenta | None]:
        """Per copy (None where its step did not end): its roots' momenta and trees; `data` is left at the
        starts' pose. The drift is the rate of the momentum at zero acceleration, the force MuJoCo's RNE needs at
        the root (`cfrc_int`, less the weight it carries)
        (tests/test_loader_momentum.py::test_the_momentum_drift_is_the_derivative_of_a_v)."""
        model, data = self.model, self.data
        self._pose([e.qpos1 if e else None for e in ended])
        kept = self._gather([e.qvel1 if e else None for e in ended])
        self._pose([e.qpos0 if e else None for e in ended])
        started = self._gather([e.qvel0 if e else None for e in ended])
        data.qacc[:] = 0.0
        mujoco.mj_rnePostConstraint(model, data)
        forces = data.cfrc_int[self.bodies]
        drifts = [
            [f + w for f, w in zip(force, weight)] + torque
            for force, weight, torque in zip(forces[:, 3:].tolist(), self.rates_weight.tolist(), forces[:, :3].tolist())
        ]
        joints_part = self._gather([e.joints_only if e else None for e in ended])
        starts = [
            self._start(body, tree, weights) for body, tree, weights in zip(self.bodies, self.trees, self.weights)
        ]
        n = len(self.roots)
        return [
            Momenta(*(x[k * n : (k + 1) * n] for x in (kept, started, joints_part, drifts, starts))) if e else None
            for k, e in enumerate(ended)
        ]

    def _pose(self, qpos: list[np.ndarray | None]) -> None:
        self.data.qpos[:] = self._joined(qpos, self.single.qpos0)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def _gather(self, qvel: list[np.ndarray | None]) -> list[list[float]]:
        """Per root of every copy, its tree's momentum at `data`'s pose and these velocities."""
        data = self.data
        data.qvel[:] = self._joined(qvel, np.zeros(self.single.nv))
        mujoco.mj_comVel(self.model, data)
        mujoco.mj_subtreeVel(self.model, data)
        linear = (data.subtree_linvel[self.bodies] * self.masses).tolist()
        return [p + a for p, a in zip(linear, data.subtree_angmom[self.bodies].tolist())]

    def _joined(self, parts: list[np.ndarray | None], filler: np.ndarray) -> np.ndarray:
        if self.copies == 1:
            return parts[0] if parts[0] is not None else filler
        return np.concatenate([part if part is not None else filler for part in parts])

    def _start(self, body: int, tree: np.ndarray, weights: np.ndarray) -> Start:
        data = self.data
        total = data.cinert[tree].sum(axis=0).tolist()
        return Start(data.subtree_com[body].tolist(), total[9], tuple(total[:6]), (weights @ data.xipos[tree]).tolist())


def stack(model: mujoco.MjModel, copies: int) -> mujoco.MjModel | None:
    """A model holding `copies` copies of `model`'s bodies and joints (no geoms, actuators or constraints: what
    the momentum's passes read), each copy's numbers those of `model`; None where the compiled stack does not
    give each copy its numbers bit for bit on a random state (`gives_each_copy_its_own`)."""
    spec = mujoco.MjSpec()
    spec.option.gravity = model.opt.gravity
    spec.option.disableflags = model.opt.disableflags
    for _ in range(copies):
        made = [spec.worldbody]
        for b in range(1, model.nbody):
            body = made[int(model.body_parentid[b])].add_body(
                pos=model.body_pos[b],
                quat=model.body_quat[b],
                mass=max(float(model.body_mass[b]), mujoco.mjMINVAL),
                ipos=model.body_ipos[b],
                iquat=model.body_iquat[b],
                inertia=np.maximum(model.body_inertia[b], mujoco.mjMINVAL),
                explicitinertial=True,
                mocap=bool(model.body_mocapid[b] >= 0),
            )
            made.append(body)
            for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
                body.add_joint(
                    type=mujoco.mjtJoint(int(model.jnt_type[j])), pos=model.jnt_pos[j], axis=model.jnt_axis[j]
                )
    try:
        stacked = spec.compile()
    except ValueError:
        return None
    if not _same_layout(model, stacked, copies):
        return None
    nb, nj = model.nbody - 1, model.njnt
    for k in range(copies):
        bodies, joints = slice(1 + k * nb, 1 + (k + 1) * nb), slice(k * nj, (k + 1) * nj)
        for name in (*BODY_NUMBERS, *BODY_FLAGS):
            getattr(stacked, name)[bodies] = getattr(model, name)[1:]
        stacked.jnt_pos[joints], stacked.jnt_axis[joints] = model.jnt_pos, model.jnt_axis
        stacked.dof_armature[k * model.nv : (k + 1) * model.nv] = model.dof_armature  # in M, which the root rows read
        stacked.qpos0[k * model.nq : (k + 1) * model.nq] = model.qpos0
    return stacked if gives_each_copy_its_own(model, stacked, copies) else None


def _same_layout(model: mujoco.MjModel, stacked: mujoco.MjModel, copies: int) -> bool:
    """Each copy's bodies, joints, positions and DoFs in a block of their own, in `model`'s order."""
    nb = model.nbody - 1
    if (stacked.nbody, stacked.njnt, stacked.nq, stacked.nv) != (
        1 + copies * nb,
        copies * model.njnt,
        copies * model.nq,
        copies * model.nv,
    ):
        return False
    parents = np.where(model.body_parentid[1:] > 0, model.body_parentid[1:], -1)
    for k in range(copies):
        body_shift = np.where(parents > 0, parents + k * nb, 0)
        joints = slice(k * model.njnt, (k + 1) * model.njnt)
        if not (
            np.array_equal(stacked.body_parentid[1 + k * nb : 1 + (k + 1) * nb], body_shift)
            and np.array_equal(stacked.jnt_type[joints], model.jnt_type)
            and np.array_equal(stacked.jnt_qposadr[joints], model.jnt_qposadr + k * model.nq)
            and np.array_equal(stacked.jnt_dofadr[joints], model.jnt_dofadr + k * model.nv)
            and np.array_equal(stacked.dof_bodyid[k * model.nv : (k + 1) * model.nv], model.dof_bodyid + k * nb)
        ):
            return False
    return True


def random_state(model: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """qpos near qpos0 (unit quaternions for ball and free joints) and a random qvel."""
    qpos = model.qpos0 + 0.3 * rng.standard_normal(model.nq)
    for j in range(model.njnt):
        kind, adr = int(model.jnt_type[j]), int(model.jnt_qposadr[j])
        if kind in (BALL, FREE):
            at = adr + (3 if kind == FREE else 0)
            qpos[at : at + 4] /= np.linalg.norm(qpos[at : at + 4])
    return qpos, rng.standard_normal(model.nv)


def gives_each_copy_its_own(model: mujoco.MjModel, stacked: mujoco.MjModel, copies: int) -> bool:
    """Whether the passes on the stack give every copy, at a random state of its own, exactly the numbers the
    passes on `model` give it."""
    rng = np.random.default_rng(0)
    states = [random_state(model, rng) for _ in range(copies)]
    alone, together = mujoco.MjData(model), mujoco.MjData(stacked)
    together.qpos[:] = np.concatenate([q for q, _ in states])
    together.qvel[:] = np.concatenate([v for _, v in states])
    stacked_dofs = _passes(stacked, together)
    nb, nv = model.nbody - 1, model.nv
    for k, (qpos, qvel) in enumerate(states):
        alone.qpos[:], alone.qvel[:] = qpos, qvel
        dofs = _passes(model, alone)
        rows = slice(1 + k * nb, 1 + (k + 1) * nb)
        if any(not np.array_equal(getattr(alone, name)[1:], getattr(together, name)[rows]) for name in CHECKED):
            return False
        if not np.array_equal(dofs, stacked_dofs[:, k * nv : (k + 1) * nv]):
            return False
    return True


def _passes(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """The passes the settle reads; returns per DoF what the root rows read: MuJoCo's bias and M qvel."""
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_comVel(model, data)
    mujoco.mj_subtreeVel(model, data)
    data.qacc[:] = 0.0
    mujoco.mj_rnePostConstraint(model, data)
    mujoco.mj_crb(model, data)
    dofs = np.zeros((2, model.nv))
    mujoco.mj_rne(model, data, 0, dofs[0])
    mujoco.mj_mulM(model, data, dofs[1], data.qvel)
    return dofs
