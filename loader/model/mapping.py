"""Where every MuJoCo body, joint, DoF and geom went in SAPIEN, and state conversion both ways.

MuJoCo's free joint stores the body-origin velocity (world axes) and the angular velocity in the body frame;
SAPIEN's floating root takes the centre-of-mass velocity and the angular velocity in world axes.
A ball joint's quaternion becomes three angles (a, b, c) with R = Rx(a) Ry(b) Rz(c), and its body-frame angular
velocity omega becomes angle rates through omega = E(a, b, c) @ rates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from . import mj
from .frames import (
    cross_floats,
    euler_xyz_from_quat,
    euler_xyz_rate_matrix,
    quat_from_euler_xyz,
    rotation_rows,
    turn,
    turn_back,
)
from .joints import BALL, DRIVEN, FREE

CARRIED = ("hinge", "slide", "free")  # joints whose share of a tendon's force SAPIEN applies


@dataclass(frozen=True)
class BodyLink:
    """A MuJoCo body in SAPIEN: a link of an articulation, or a static actor (`articulation` None)."""

    articulation: int | None
    link: int | None
    actor: int | None = None


@dataclass(frozen=True)
class JointDofs:
    """A MuJoCo joint in SAPIEN: indices into `art.get_qpos()` (3 for a ball, none for a free joint)."""

    articulation: int
    kind: str
    dofs: tuple[int, ...]

    @property
    def drive_key(self) -> tuple[int, int] | None:
        """(articulation, SAPIEN dof) of a hinge or slide, the key of its drive DoF; None for a ball or free joint."""
        return (self.articulation, self.dofs[0]) if self.kind in DRIVEN else None


@dataclass(frozen=True)
class GeomShape:
    """A MuJoCo geom's collision shape: index into the link's (or the actor's) `collision_shapes`."""

    articulation: int | None
    link: int | None
    actor: int | None
    shape: int


def centres(model: mujoco.MjModel) -> np.ndarray:
    """Each body's link's centre of mass in the body frame: MuJoCo's, or the origin for a massless body, whose
    `body_ipos` MuJoCo leaves at the body's position in its parent. A helper mass there, far from the tree's real
    mass, makes PhysX's articulation ill-conditioned: a falling rigid tree starts turning
    (tests/test_loader_free_joint.py::test_a_massless_root_carrying_a_heavy_child_falls_without_turning)."""
    return np.where(model.body_mass[:, None] > 0, model.body_ipos, 0.0)


def root_state(art, ipos: np.ndarray) -> tuple[list[float], list[float]]:
    """A floating root's MuJoCo free-joint qpos (7) and qvel (6: the body origin's velocity in the world, the
    angular velocity in the body frame) from PhysX's root pose and centre-of-mass velocities."""
    root = art.get_root_pose()
    position, quat = root.p.tolist(), root.q.tolist()
    rotation = rotation_rows(quat)
    omega = art.get_root_angular_velocity().tolist()
    v_com = art.get_root_linear_velocity().tolist()
    arm = turn(rotation, ipos.tolist())
    origin = [v - w for v, w in zip(v_com, cross_floats(omega, arm))]
    return position + quat, origin + list(turn_back(rotation, omega))


def scalar_joints(mapping) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """Per articulation: (index, qpos addresses, dof addresses, SAPIEN dofs) of its hinges and slides."""
    groups: dict[int, list[tuple[int, int, int]]] = {}
    for j, target in enumerate(mapping.joints):
        if int(mapping.jnt_type[j]) not in (FREE, BALL) and target.dofs:
            groups.setdefault(target.articulation, []).append(
                (int(mapping.jnt_qposadr[j]), int(mapping.jnt_dofadr[j]), target.dofs[0])
            )
    return [(a, *(np.array(column, dtype=int) for column in zip(*rows))) for a, rows in groups.items()]


@dataclass
class Mapping:
    bodies: list[BodyLink]
    joints: list[JointDofs]
    geoms: list[GeomShape | None]
    articulation_dofs: list[int]
    # constants copied from the compiled model for the conversions
    jnt_type: np.ndarray = field(repr=False, default=None)
    jnt_qposadr: np.ndarray = field(repr=False, default=None)
    jnt_dofadr: np.ndarray = field(repr=False, default=None)
    jnt_bodyid: np.ndarray = field(repr=False, default=None)
    centres: np.ndarray = field(repr=False, default=None)  # each body's link's centre of mass (`tree.centres`)
    nq: int = 0
    nv: int = 0

    @classmethod
    def from_model(cls, model: mujoco.MjModel, bodies, joints, geoms, articulation_dofs) -> Mapping:
        return cls(
            bodies,
            joints,
            geoms,
            articulation_dofs,
            model.jnt_type.copy(),
            model.jnt_qposadr.copy(),
            model.jnt_dofadr.copy(),
            model.jnt_bodyid.copy(),
            centres(model),
            model.nq,
            model.nv,
        )

    @property
    def dofs(self) -> list[tuple[int, int | None]]:
        """Per MuJoCo DoF: (articulation, SAPIEN DoF index), the index None for a floating root's six DoFs."""
        result: list[tuple[int, int | None]] = [(-1, None)] * self.nv
        for j, target in enumerate(self.joints):
            adr = int(self.jnt_dofadr[j])
            if target.kind == "free":
                for k in range(6):
                    result[adr + k] = (target.articulation, None)
            for k, dof in enumerate(target.dofs):
                result[adr + k] = (target.articulation, dof)
        return result

    def joint_dofs_only(self, model: mujoco.MjModel, dofs: set[int]) -> bool:
        """Whether every one of these MuJoCo DoFs is a hinge's or a slide's, so a force on them is joint forces
        SAPIEN applies (`set_qf`)."""
        return all(self.joints[int(model.dof_jntid[d])].kind in DRIVEN for d in dofs)

    def carries(self, model: mujoco.MjModel, tendon: int) -> bool:
        """Whether SAPIEN can apply a force along the tendon: every DoF it moves is a mapped hinge, slide or free
        joint."""
        return all(self.joints[int(model.dof_jntid[d])].kind in CARRIED for d in mj.tendon_dofs(model, tendon))

    def mujoco_dofs(self) -> dict[tuple[int, int], int]:
        """(articulation, SAPIEN DoF) -> MuJoCo DoF, for every DoF a SAPIEN joint carries."""
        return {key: d for d, key in enumerate(self.dofs) if key[1] is not None}

    def set_state(self, articulations, qpos, qvel=None) -> None:
        """Put MuJoCo's (qpos, qvel) into the SAPIEN articulations."""
        qpos = np.asarray(qpos, dtype=np.float64)
        qvel = np.zeros(self.nv) if qvel is None else np.asarray(qvel, dtype=np.float64)
        q = [np.zeros(n) for n in self.articulation_dofs]
        v = [np.zeros(n) for n in self.articulation_dofs]
        for j, target in enumerate(self.joints):
            a, adr, dof = target.articulation, int(self.jnt_qposadr[j]), int(self.jnt_dofadr[j])
            jtype = int(self.jnt_type[j])
            if jtype == FREE:
                self.set_root(articulations[a], int(self.jnt_bodyid[j]), qpos[adr : adr + 7], qvel[dof : dof + 6])
            elif jtype == BALL:
                angles = euler_xyz_from_quat(qpos[adr : adr + 4])
                q[a][list(target.dofs)] = angles
                v[a][list(target.dofs)] = np.linalg.solve(euler_xyz_rate_matrix(angles), qvel[dof : dof + 3])
            else:
                q[a][target.dofs[0]] = qpos[adr]
                v[a][target.dofs[0]] = qvel[dof]
        for art, qa, va in zip(articulations, q, v):
            # also for a tree without DoF: setting qpos is what updates its links' poses
            art.set_qpos(qa.astype(np.float32))
            art.set_qvel(va.astype(np.float32))

    def set_root(self, art, body: int, qpos7, qvel6) -> None:
        """A floating root's MuJoCo free-joint qpos (7) and qvel (6) into PhysX's root pose and velocities."""
        qpos7, qvel6 = np.asarray(qpos7, np.float64).tolist(), np.asarray(qvel6, np.float64).tolist()
        rotation = rotation_rows(qpos7[3:])
        omega_world = turn(rotation, qvel6[3:])
        arm = cross_floats(omega_world, turn(rotation, self.centres[body].tolist()))
        norm = math.sqrt(sum(c * c for c in qpos7[3:]))
        art.set_root_pose(sapien.Pose(qpos7[:3], [c / norm for c in qpos7[3:]]))
        art.set_root_linear_velocity(np.array([v + a for v, a in zip(qvel6[:3], arm)], np.float32))
        art.set_root_angular_velocity(np.array(omega_world, np.float32))

    def get_state(
        self, articulations, q: list | None = None, v: list | None = None, roots: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """Read SAPIEN's state back in MuJoCo's layout (qpos of size nq, qvel of size nv); `q`, `v`: the
        articulations' joint positions and velocities when already read; `roots=False` leaves the free joints'
        entries zero."""
        qpos = np.zeros(self.nq)
        qvel = np.zeros(self.nv)
        q = q if q is not None else [np.asarray(art.get_qpos(), np.float64) for art in articulations]
        v = v if v is not None else [np.asarray(art.get_qvel(), np.float64) for art in articulations]
        self._index()
        for a, qadr, dadr, dofs in self._scalars:
            qpos[qadr] = q[a][dofs]
            qvel[dadr] = v[a][dofs]
        for j in self._rotating:
            target = self.joints[j]
            a, adr, dof = target.articulation, int(self.jnt_qposadr[j]), int(self.jnt_dofadr[j])
            jtype = int(self.jnt_type[j])
            if jtype == FREE and roots:
                qpos[adr : adr + 7], qvel[dof : dof + 6] = root_state(
                    articulations[a], self.centres[int(self.jnt_bodyid[j])]
                )
            elif jtype == BALL:
                angles = q[a][list(target.dofs)]
                qpos[adr : adr + 4] = quat_from_euler_xyz(angles)
                qvel[dof : dof + 3] = euler_xyz_rate_matrix(angles) @ v[a][list(target.dofs)]
        return qpos, qvel

    def qfrc_to_sapien(self, qfrc, articulations=None) -> list[np.ndarray]:
        """A MuJoCo generalized force (nv) as per-articulation arrays for `art.set_qf` (a free joint has none: its share
        is a wrench on the root link, `Controller.push`).

        Ball joints need the current angles (from `articulations`): power is invariant, tau . omega =
        tau . E rates, so the angle-rate force is E^T tau.
        """
        qfrc = np.asarray(qfrc, dtype=np.float64)
        out = [np.zeros(n) for n in self.articulation_dofs]
        self._index()
        for a, _, dadr, dofs in self._scalars:
            out[a][dofs] = qfrc[dadr]
        for j in self._rotating:
            target = self.joints[j]
            if int(self.jnt_type[j]) != BALL:
                continue
            if articulations is None:
                raise ValueError("a ball joint's force conversion needs the articulations' current angles")
            a, dof = target.articulation, int(self.jnt_dofadr[j])
            angles = np.asarray(articulations[a].get_qpos(), np.float64)[list(target.dofs)]
            out[a][list(target.dofs)] = euler_xyz_rate_matrix(angles).T @ qfrc[dof : dof + 3]
        return out

    def _index(self) -> None:
        """The hinges' and slides' addresses per articulation (`scalar_joints`) and the free and ball joints, found
        once."""
        if getattr(self, "_scalars", None) is None:
            self._scalars = scalar_joints(self)
            self._rotating = [j for j in range(len(self.joints)) if int(self.jnt_type[j]) in (FREE, BALL)]
