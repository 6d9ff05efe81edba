"""Tendons every step: fixed tendons' springs and dampers over their joints, spatial tendons' along the path MuJoCo
computes at SAPIEN's pose, and the paths themselves, which tendon actuators read too (`actuators.py`).

A fixed tendon's force is J^T f with J its constant coefficients. A spatial tendon's length and Jacobian J (over
MuJoCo's DoFs) change with the pose, so MuJoCo computes them at SAPIEN's state each step (`mj_kinematics`,
`mj_comPos`, `mj_tendon` on a data of the loaded model), once per step for every consumer. A generalized force J^T f
over the tendons' DoFs is joint forces on hinges and slides and, on a free joint (a tendon anchored off the floating
tree), a wrench on the root link (`RootPush`). A spring acts between `lengthspring`'s ends (a dead band). MuJoCo's
implicitfast holds a damper's or kv's whole J^T J implicitly; a drive holds one DoF, so the diagonal joins the drives
and the rest stays explicit (`COUPLED_DAMPING` notes it) (tests/test_loader_passive.py,
tests/test_loader_spatial_tendons.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..model import mj
from ..model.joints import DRIVEN
from ..model.mapping import Mapping
from ..model.options import IMPLICIT
from .dof_step import Step
from .integrated import RootPush
from .rows import scalar_state
from .term import Compilation, Term

COUPLED_DAMPING = (
    "damping implicit in its diagonal b J_i^2 only (MuJoCo's implicit integrators hold the whole "
    "b J^T J; the off-diagonal part is explicit)"
)


def tendon_state(terms, q: list[np.ndarray], v: list[np.ndarray]) -> tuple[float, float]:
    """Length and rate, sum c q and sum c qdot, of a fixed tendon over (articulation, dof, coefficient) terms."""
    return (sum(c * q[art][dof] for art, dof, c in terms), sum(c * v[art][dof] for art, dof, c in terms))


@dataclass(frozen=True)
class PassiveTendon:
    """A fixed tendon's spring (dead band `low`..`high`) and damper as MuJoCo applies them, over (articulation,
    dof, coefficient) terms: the force J^T f from the state, explicit, written by `set_ctrl` every step. MuJoCo's
    implicitfast holds the damper's whole D J^T J implicitly; a drive holds one DoF, so the diagonal D c_i^2 joins
    the joints' drives, `forces` adds D c_i^2 qdot_i back, and the off-diagonal part stays explicit (exact for a
    tendon over one joint; `COUPLED_DAMPING` notes the others)."""

    name: str
    terms: tuple[tuple[int, int, float], ...]
    stiffness: float
    damping: float
    low: float
    high: float

    def forces(self, q: list[np.ndarray], v: list[np.ndarray], implicit: bool):
        """Per term (articulation, dof, explicit force, implicit damping for the drive): the diagonal D c^2 is
        implicit under MuJoCo's implicit integrators (`implicit`), explicit under Euler."""
        length, rate = tendon_state(self.terms, q, v)
        stretch = length - self.low if length < self.low else (length - self.high if length > self.high else 0.0)
        pull = -self.stiffness * stretch - self.damping * rate
        for art, dof, c in self.terms:
            diagonal = self.damping * c * c if implicit else 0.0
            yield art, dof, c * pull + diagonal * v[art][dof], diagonal


COUPLED_DAMPING = (
    "damping implicit in its diagonal b J_i^2 only (MuJoCo's implicit integrators hold the whole "
    "b J^T J; the off-diagonal part is explicit)"
)


def map_tendons(model: mujoco.MjModel, mapping, notes) -> list[PassiveTendon]:
    """Passive tendon properties: a fixed tendon's spring and damper, applied as MuJoCo does (`PassiveTendon`;
    Euler takes the damper explicitly). A PhysX fixed tendon would be implicit in its spring too
    (tests/test_loader_passive.py::test_a_passive_fixed_tendon_matches_mujoco)."""
    out, passive = [], mj.tendon_passive(model)
    for t in range(model.ntendon):
        name = mj.name(model, "tendon", t)
        terms = mj.fixed_tendon_terms(model, t)
        if not terms:
            continue  # a spatial tendon (`spatial_tendons.py`)
        if model.tendon_armature[t] > 0:
            notes.drop("tendon", name, f"tendon armature {model.tendon_armature[t]:g} not mapped")
        stiffness, damping = float(passive[0][t]), float(passive[1][t])
        if stiffness == 0 and damping == 0:
            continue  # a transmission only: actuators and equalities read it
        mapped = []
        for joint, coefficient in terms:
            target = mapping.joints[joint]
            if target.drive_key is None:
                notes.drop("tendon", name, "crosses a ball or free joint")
                break
            mapped.append((*target.drive_key, coefficient))
        else:
            if damping and len(mapped) > 1 and int(model.opt.integrator) in IMPLICIT:
                notes.approximate("tendon", name, COUPLED_DAMPING)
            low, high = (float(x) for x in model.tendon_lengthspring[t])
            out.append(PassiveTendon(name, tuple(mapped), stiffness, damping, low, high))
    return out


class TendonPaths:
    """The spatial tendons `tendons` (MuJoCo ids) over the DoFs `dofs` (MuJoCo's) they move: the hinge and slide
    ones SAPIEN's `keys` (columns `joint`)."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, tendons: list[int]):
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.tendons = np.array(tendons, dtype=int)
        dofs = sorted(set().union(*(mj.tendon_dofs(model, t) for t in tendons)))
        self.over(dofs)
        column = {d: i for i, d in enumerate(dofs)}  # MuJoCo keeps ten_J sparse, its pattern fixed by the model
        entries = [
            (k, column[int(model.ten_J_colind[a])], a)
            for k, t in enumerate(tendons)
            for a in range(int(model.ten_J_rowadr[t]), int(model.ten_J_rowadr[t] + model.ten_J_rownnz[t]))
        ]
        self.row, self.column, self.entry = (np.array(x, dtype=int) for x in zip(*entries))
        self.last: tuple | None = None  # (step, its state): one pass per step for every consumer

    def over(self, dofs: list[int]) -> None:
        """The paths move MuJoCo's DoFs `dofs` (sorted): `joint` marks the hinges and slides, whose SAPIEN DoFs are
        `keys`; `floating`, a free joint among them."""
        model, mapping = self.model, self.mapping
        self.dofs = np.array(dofs, dtype=int)
        targets = [mapping.joints[int(model.dof_jntid[d])] for d in dofs]
        self.joint = np.array([t.kind in DRIVEN for t in targets], dtype=bool)
        self.floating = not self.joint.all()
        self.keys = [(t.articulation, t.dofs[0]) for t, on in zip(targets, self.joint) if on]

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

    def pose(self, qpos: np.ndarray) -> mujoco.MjData:
        """The paths' data at MuJoCo's `qpos`: body poses and the tendons' lengths and Jacobian."""
        model, data = self.model, self.data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        return data

    def measure(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tendons' lengths and Jacobian (tendon x `dofs`) at MuJoCo's `qpos`."""
        data = self.pose(qpos)
        return data.ten_length[self.tendons], self.dense(data)

    def dense(self, data: mujoco.MjData) -> np.ndarray:
        """The tendons' rows of MuJoCo's sparse ten_J, over `dofs`."""
        jacobian = np.zeros((len(self.tendons), len(self.dofs)))
        jacobian[self.row, self.column] = data.ten_J[self.entry]
        return jacobian

    def apply(
        self,
        step: Step,
        force: np.ndarray,
        push: RootPush | None,
        jacobian: np.ndarray,
        v: np.ndarray,
        implicit: np.ndarray | None = None,
    ) -> None:
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


class AlongPaths:
    """A force along some of the spatial tendons of `paths` (`rows`: their rows there), its share on a free joint
    pushed on the root link (`push`, None where every DoF the paths move is a hinge or slide)."""

    def __init__(self, paths: TendonPaths, tendons: list[int]):
        self.paths = paths
        self.rows = np.array([paths.index(t) for t in tendons], dtype=int)
        self.push = RootPush(paths.model, paths.mapping) if paths.floating else None

    @property
    def applied(self) -> list | tuple:
        """This step's root wrenches (the momentum term's)."""
        return self.push.applied if self.push is not None else ()

    def compile(self, layout) -> None:
        self.paths.compile(layout)


class SpatialTendons(AlongPaths):
    """The passive spatial tendons `tendons` (MuJoCo ids) along `paths`; `implicit`: MuJoCo's integrator holds
    dampers implicitly."""

    def __init__(self, paths: TendonPaths, tendons: list[int], implicit: bool):
        super().__init__(paths, tendons)
        model = paths.model
        stiffness, damping = mj.tendon_passive(model)
        self.stiffness, self.damping = stiffness[tendons], damping[tendons]
        self.low, self.high = model.tendon_lengthspring[tendons].T.copy()
        self.implicit = implicit and bool(self.damping.any())  # the dampers' diagonal joins the drives

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


def plan_spatial(
    model: mujoco.MjModel, mapping: Mapping, notes, implicit: bool, paths: TendonPaths | None
) -> SpatialTendons | None:
    """The spatial tendons with a spring or damper along `paths` (those SAPIEN can carry: `Mapping.carries`;
    a tendon whose path crosses a ball joint is noted and left out)."""
    stiffness, damping = mj.tendon_passive(model)
    tendons = []
    for t in range(model.ntendon):
        if not mj.is_spatial(model, t) or not (stiffness[t] or damping[t]):
            continue
        name = mj.name(model, "tendon", t)
        if not mapping.carries(model, t):
            notes.drop(
                "tendon",
                name,
                "spatial tendon's spring and damper not mapped: the tendon moves a ball "
                "joint, whose torque SAPIEN's joint forces do not take",
            )
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
    tendons = [
        t
        for t in range(model.ntendon)
        if mj.is_spatial(model, t) and mapping.carries(model, t) and (t in actuated or stiffness[t] or damping[t])
    ]
    return TendonPaths(model, mapping, tendons) if tendons else None


class TendonTerm(Term):
    """The passive fixed tendons' forces every step, as arrays over their terms (per term its tendon `owner`,
    joint position `flat`, drive column and coefficient), and the spatial ones' (`spatial`); under implicit
    integrators their dampers' diagonal joins the drives (`Step.implicit_extra`)."""

    name = "tendons"

    def __init__(self, tendons: list[PassiveTendon], spatial=None):
        self.tendons, self.spatial = tendons, spatial

    @property
    def applied(self) -> list | tuple:
        return self.spatial.applied if self.spatial is not None else ()

    def compile(self, compilation: Compilation) -> None:
        layout = compilation.layout
        if self.spatial is not None:
            self.spatial.compile(layout)
        rows = [(k, (art, dof), c) for k, t in enumerate(self.tendons) for art, dof, c in t.terms]
        self.owner = np.array([k for k, _, _ in rows], dtype=int)
        self.flat = layout.flat_of([key for _, key, _ in rows])
        self.drive = layout.drive_of([key for _, key, _ in rows])
        self.coefficient = np.array([c for _, _, c in rows], dtype=np.float64)
        columns = np.array([(t.stiffness, t.damping, t.low, t.high) for t in self.tendons], np.float64).reshape(-1, 4)
        self.stiffness, self.damping, self.low, self.high = columns.T.copy()
        self.pulling = -self.stiffness
        self.diagonal = self.damping[self.owner] * self.coefficient * self.coefficient  # D c^2 per term
        self.unique = len(set(self.flat.tolist())) == self.flat.size  # no DoF in two terms: no sums

    def contribute(self, step) -> None:
        """`PassiveTendon.forces` for every fixed tendon at once, then the spatial ones."""
        if self.spatial is not None:
            self.spatial.contribute(step)
        if not self.tendons:
            return
        owner, c, count = self.owner, self.coefficient, len(self.tendons)
        v = step.v[self.flat]
        length = np.bincount(owner, c * step.q[self.flat], minlength=count)
        rate = np.bincount(owner, c * v, minlength=count)
        stretch = np.where(length < self.low, length - self.low, np.where(length > self.high, length - self.high, 0.0))
        pull = self.pulling * stretch - self.damping * rate
        implicit = not step.explicit_kv  # the dampers' diagonal joins the drives
        force = c * pull[owner] + self.diagonal * v if implicit else c * pull[owner]
        if self.unique:
            step.force[self.flat] += force
            if implicit:
                extra = step.law[5]
                extra[self.drive] += self.diagonal
        else:
            np.add.at(step.force, self.flat, force)
            if implicit:
                np.add.at(step.law[5], self.drive, self.diagonal)

    def implicit_diagonal(self) -> dict[tuple[int, int], float]:
        """The dampers' diagonal D c^2 per DoF (what joins the drives under implicit integrators)."""
        out: dict[tuple[int, int], float] = {} if self.spatial is None else self.spatial.implicit_diagonal()
        for tendon in self.tendons:
            for art, dof, c in tendon.terms:
                out[(art, dof)] = out.get((art, dof), 0.0) + tendon.damping * c * c
        return out
