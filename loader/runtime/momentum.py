"""A floating robot's root velocity after a PhysX step, in MuJoCo's convention.

Both simulators give the joints the same velocities over a step; they differ in what the floating root keeps.
PhysX's articulation step conserves momentum: the linear momentum ends at P(q0, v0) + dt F (F: gravity and the
link forces), and the angular momentum about the centre of mass keeps the size of L(q0, v0) + dt T (T: their
torque about it) while taking its direction from an uncorrected intermediate. MuJoCo's semi-implicit Euler keeps
qvel: its momentum ends at A(q0) v1 = (P, L)(q0, v0) + dt (F, T) - dt (dA/dt) v0, A the centroidal momentum
matrix. Where the links turn relative to each other within a step, the roots end with different velocities.

`Momentum.settle` recovers MuJoCo's root velocity after a physics step, the joint part of v1 PhysX's, and writes
the root pose MuJoCo's position update gives. Where every force on the tree is known (no contact pushed it, no D6
joint holds it), MuJoCo's own step on the free joint's rows gives it:

    M_rr(q0) (v1_r - v0_r) = dt (tau_r - c_r(q0, v0)) - M_rj(q0) (v1_j - v0_j),

tau_r the free joint's share of the link forces and of the gravity PhysX does not apply (`root_rows`). Elsewhere it
solves A(q0) v1 = (P', L) - dt (dA/dt) v0, with P' PhysX's end linear momentum and L the start's angular momentum
plus dt T, scaled to PhysX's end size; a tree a contact pushed keeps PhysX's L: SAPIEN reports a contact's normal
impulse only, so the torque of friction is unknown
(tests/test_loader_momentum.py::test_a_tree_a_contact_turns_keeps_physxs_angular_momentum).
It acts only where the joints moved exactly as PhysX's position update moves them (position by timestep x
velocity): not after a `set_state`, where contacts corrected positions, or on a second read.
(tests/test_loader_momentum.py::test_a_free_robot_kicked_by_its_joints_keeps_mujocos_root_velocity)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import Notes
from ..model import mj
from ..model.frames import Vec3, cross_floats, rotation_rows, solve_symmetric, turn_back
from ..model.joints import BALL, FREE
from ..model.mapping import Mapping
from .centroidal import Ended, Momenta, Passes, Start, stack
from .free_joint import FreeJointLaw, differs
from .term import Term

ISOTROPIC = 1e-9  # relative spread of a body's principal moments below which its spin never turns it
MOVED = 1e-6  # joint positions (rad, m) agree with timestep x velocity to float32 rounding (plus this, relative)


def pose7(art) -> tuple[float, ...]:
    pose = art.get_root_pose()
    return tuple(pose.p.tolist() + pose.q.tolist())


def advanced(qpos7: np.ndarray, qvel6, dt: float) -> np.ndarray:
    """A free joint's position after MuJoCo's position update: origin by dt times its velocity, orientation turned
    by dt times the body-frame angular velocity."""
    out = np.array(qpos7, np.float64)
    out[:3] += dt * np.asarray(qvel6[:3])
    mujoco.mju_quatIntegrate(out[3:], np.asarray(qvel6[3:], np.float64), dt)
    return out


def angular(kept, carried) -> list[float]:
    """The angular momentum the step carried: PhysX keeps its size and loses its direction (it rescales an
    uncorrected intermediate's); `carried` is the start's plus dt times the external torque, all of it known where
    no contact pushed the tree (`touching`)."""
    size, norm = math.sqrt(sum(c * c for c in kept)), math.sqrt(sum(c * c for c in carried))
    return [c * (size / norm) for c in carried] if norm > 0.0 else list(kept)


def touching(links: set, contacts) -> bool:
    """Whether a contact pushed one of `links` in the last step."""
    return any(
        body in links
        for contact in contacts
        for body in contact.bodies
        if any(np.any(point.impulse) for point in contact.points)
    )


def external_torque(start: Start, root, gravity: tuple, wrenches) -> Vec3:
    """External torque about the root's tree's centre of mass at the step's start (`start`): gravity on the links
    it acts on and the loader's link forces (articulation, point, force, torque)."""
    centre, weight = start.centre, root.weight
    arm = [m - weight * c for m, c in zip(start.moment, centre)]
    torque = cross_floats(arm, gravity)
    for a, point, force, moment in wrenches:
        if a == root.articulation:
            lever = cross_floats([p - c for p, c in zip(point, centre)], force)
            torque = tuple(t + float(m) + f for t, m, f in zip(torque, moment, lever))
    return torque


@dataclass(frozen=True, eq=False)
class Root:
    """A floating articulation's root: its free joint's addresses, its tree's bodies and DoFs, and the mass gravity
    pulls on per body of the tree (none of a compensated body's)."""

    articulation: int
    body: int
    qposadr: int
    dofadr: int
    tree: np.ndarray
    dofs: np.ndarray
    weights: np.ndarray
    damped: bool  # MuJoCo's step adds to the free joint what PhysX's does not (`FreeJointLaw`)
    weight: float  # the tree's mass gravity pulls on (the sum of `weights`)
    held: bool = False  # a connect or weld holds a body of the tree
    lifted: tuple = ()  # (body, -gravcomp m g) per compensated body of the tree

    @property
    def balanced(self) -> bool:
        """Whether MuJoCo's root rows settle it where no contact pushed it (`Passes.root_rows`): every force on
        the tree is then known, and the free joint adds nothing to PhysX's step."""
        return not (self.damped or self.held)


class Momentum(Term):
    """Per floating articulation (`Root`): the root's velocity after each PhysX step as MuJoCo's step leaves it."""

    name = "momentum"

    def __init__(
        self, model: mujoco.MjModel, mapping: Mapping, roots: list[Root], timestep: float, scene=None, articulations=()
    ):
        self.model, self.mapping, self.roots = model, mapping, roots
        self.timestep = timestep
        self.start: tuple | None = None  # at the last set_ctrl: MuJoCo's qpos and qvel, SAPIEN's joint positions
        gravity = mj.gravity(model)
        self.gravity = tuple(gravity.tolist())
        self.passes = Passes(model, model, roots, gravity)  # on this copy's own data
        self.data = self.passes.data
        self.root_dofs = np.concatenate([np.arange(root.dofadr, root.dofadr + 6) for root in roots])
        self.scene = scene
        self.sees_contacts = scene is not None  # SAPIEN's contacts are on (`contacts`)
        self.links = {root.articulation: set(articulations[root.articulation].links) for root in roots}
        damped = [root for root in roots if root.damped]
        self.law = FreeJointLaw(model, mapping, damped, timestep) if damped else None

    def contribute(self, step) -> None:
        """Remember the state this physics step starts from (`set_ctrl` settles the last step before)."""
        q = step.layout.split(step.q)
        qpos, qvel = step.mujoco_state(self.mapping)
        arts = step.articulations
        self.start = (
            qpos,
            qvel,
            [q[r.articulation].copy() for r in self.roots],
            [pose7(arts[r.articulation]) for r in self.roots],
        )

    def forget(self) -> None:
        """The state was set from outside: the next read is not the end of a step."""
        self.start = None

    def removed(self, joints: list[list]) -> None:
        """Switched off: the next read is not the end of a step either."""
        self.start = None

    def contacts(self, enabled: bool) -> None:
        self.sees_contacts = enabled

    def settle(self, articulations, wrenches=()) -> None:
        """Once after a physics step: each floating root's velocity as MuJoCo's step leaves it. `wrenches`: the
        link forces the loader added this step, (articulation, point, force, torque) in the world."""
        ended = self.ended(articulations)
        if ended is not None:
            if ended.balanced:
                self.passes.root_rows([ended], [wrenches], self.timestep)
            (momenta,) = self.passes.momenta([ended]) if ended.unbalanced else (None,)
            self.finish(ended, momenta, articulations, wrenches)

    def ended(self, articulations) -> Ended | None:
        """The physics step since `contribute`, read back; None where none ended (a read before the step, or
        after a `set_state`) or no root stepped as PhysX's position update moves it."""
        if self.start is None:
            return None
        qpos0, qvel0, joints0, poses0 = self.start
        dt = self.timestep
        q = [np.asarray(art.get_qpos(), np.float64) for art in articulations]
        v = [np.asarray(art.get_qvel(), np.float64) for art in articulations]
        stepped, still = [], True
        for root, q0, pose0 in zip(self.roots, joints0, poses0):
            a = root.articulation
            still = still and np.array_equal(q[a], q0) and pose7(articulations[a]) == pose0
            if np.abs(q[a] - q0 - dt * v[a]).max(initial=0.0) <= MOVED * (1.0 + np.abs(q[a]).max(initial=0.0)):
                stepped.append(root)
        if still:
            return None  # read before the physics step: it is still to come
        self.start = None
        if not stepped:
            return None
        contacts = self.scene.get_contacts() if self.sees_contacts else []
        balanced = [r for r in stepped if r.balanced and not touching(self.links[r.articulation], contacts)]
        # the roots' end state is read only where the momenta are (`Passes.momenta`)
        qpos1, qvel1 = self.mapping.get_state(articulations, q, v, roots=len(balanced) < len(stepped))
        joints_only = qvel1.copy()
        joints_only[self.root_dofs] = 0.0
        return Ended(qpos0, qvel0, qpos1, qvel1, joints_only, stepped, contacts, balanced)

    def finish(self, ended: Ended, momenta: Momenta | None, articulations, wrenches) -> None:
        """The roots that stepped at MuJoCo's velocity and position after the step: the balanced ones' velocities
        already in `ended.qvel1` (`Passes.root_rows`), the others' from the passes' `momenta` (the free joint law
        reads `self.data`, which must then be at the step's start)."""
        dt, qpos0, qvel1, balanced = self.timestep, ended.qpos0, ended.qvel1, ended.balanced
        for i, root in enumerate(self.roots):
            if root not in ended.stepped or root in balanced:
                continue
            kept, start = momenta.kept[i], momenta.starts[i]
            # a balanced root left to the momenta is one a contact pushed (`ended`), whose friction torque is unseen
            if root.balanced or touching(self.links[root.articulation], ended.contacts):  # PhysX's L
                k = kept
            else:
                torque = external_torque(start, root, self.gravity, wrenches)
                carried = [s + dt * t for s, t in zip(momenta.started[i][3:], torque)]
                k = kept[:3] + angular(kept[3:], carried)
            own = [a - dt * b - c for a, b, c in zip(k, momenta.drifts[i], momenta.joints_part[i])]  # at q0
            dof = root.dofadr
            qvel1[dof : dof + 6] = root_velocity(root, start, own, qpos0)
        if self.law is not None:  # `self.data` is still at q0
            self.law.correct(self.data, [r for r in ended.stepped if r.damped], ended.qvel0, qvel1, articulations)
        for root in ended.stepped:
            adr, dof = root.qposadr, root.dofadr
            self.mapping.set_root(
                articulations[root.articulation],
                root.body,
                advanced(qpos0[adr : adr + 7], qvel1[dof : dof + 6], dt),
                qvel1[dof : dof + 6],
            )
            articulations[root.articulation].set_qvel(articulations[root.articulation].get_qvel())  # links follow


def root_velocity(root: Root, start: Start, own: list[float], qpos0: np.ndarray) -> list[float]:
    """The free joint's velocity (qvel, 6) that carries the root's own momentum `own` (linear, angular about the
    tree's centre of mass) at q0, from the tree's composite inertia there (`start`)."""
    adr = root.qposadr
    offset = [c - o for c, o in zip(start.centre, qpos0[adr : adr + 3].tolist())]  # from the origin
    omega = solve_symmetric(start.inertia, own[3:])
    linear = [p / start.mass - w for p, w in zip(own[:3], cross_floats(omega, offset))]
    return linear + list(turn_back(rotation_rows(qpos0[adr + 3 : adr + 7]), omega))


def stacked_passes(term: Momentum, copies: int) -> Passes | None:
    """The passes for `copies` copies of `term`'s model at once, on one model that holds them all
    (`centroidal.stack`); None where the stack is not exact."""
    stacked = stack(term.model, copies)
    return None if stacked is None else Passes(stacked, term.model, term.roots, np.array(term.gravity), copies)


def settle_copies(terms: list[Momentum], passes: Passes, articulations: list[list], wrenches: list[list]) -> None:
    """`Momentum.settle` for copies of one model (a `Batch`'s), each with its own term, articulations and wrenches,
    with MuJoCo's passes run once for every copy on the stack (`passes`). No term may carry a free joint law,
    which reads its own data."""
    ended = [term.ended(arts) for term, arts in zip(terms, articulations)]
    if not any(ended):
        return
    balanced = [one if one is not None and one.balanced else None for one in ended]
    if any(balanced):
        passes.root_rows(balanced, wrenches, terms[0].timestep)
    unbalanced = [one if one is not None and one.unbalanced else None for one in ended]
    momenta = passes.momenta(unbalanced) if any(unbalanced) else unbalanced
    for term, one, each, arts, pushed in zip(terms, ended, momenta, articulations, wrenches):
        if one is not None:
            term.finish(one, each, arts, pushed)


def held_bodies(model: mujoco.MjModel) -> set[int]:
    """The bodies a connect or weld equality names (its sites' bodies)."""
    held = set()
    for e in range(model.neq):
        if int(model.eq_type[e]) not in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)):
            continue
        for obj in (int(model.eq_obj1id[e]), int(model.eq_obj2id[e])):
            site = int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE)
            held.add(int(model.site_bodyid[obj]) if site and obj >= 0 else obj)
    return held


def plan_momentum(
    model: mujoco.MjModel, mapping: Mapping, articulations: list, timestep: float, notes: Notes, scene=None
) -> Momentum | None:
    """The floating articulations (None without any) whose step differs between PhysX and MuJoCo: those with joints
    or several bodies, with a free joint law (`free_joint.differs`), or a lone body whose spin turns under its own
    inertia (principal moments not all equal, or the centre of mass off the origin)."""
    roots = []
    centres = mapping.centres
    held = held_bodies(model)
    gravity = mj.gravity(model)
    for j, target in enumerate(mapping.joints):
        if int(model.jnt_type[j]) != FREE:
            continue
        body, dof = int(model.jnt_bodyid[j]), int(model.jnt_dofadr[j])
        tree = np.flatnonzero(model.body_rootid == body)
        damped = differs(model, j, tree)
        inertia = model.body_inertia[body]
        spinning = (
            tree.size > 1 or np.any(centres[body]) or not np.allclose(inertia, inertia.mean(), rtol=ISOTROPIC, atol=0.0)
        )
        if articulations[target.articulation].dof == 0 and not damped and not spinning:
            continue
        dofs = np.flatnonzero(np.isin(model.dof_bodyid, tree))
        if damped and np.any(np.isin(model.jnt_type[np.isin(model.jnt_bodyid, tree)], BALL)):
            notes.approximate(
                "joint",
                mj.name(model, "joint", j),
                "free joint damping or armature: the tree's ball "
                "joints keep PhysX's velocity where MuJoCo's couples them to the root's",
            )
        weights = model.body_mass[tree] * (1.0 - model.body_gravcomp[tree])
        lifted = tuple(
            (int(b), -float(model.body_gravcomp[b] * model.body_mass[b]) * gravity)
            for b in tree
            if model.body_gravcomp[b] and gravity.any()
        )
        roots.append(
            Root(
                target.articulation,
                body,
                int(model.jnt_qposadr[j]),
                dof,
                tree,
                dofs,
                weights,
                damped,
                float(weights.sum()),
                bool(held & set(tree.tolist())),
                lifted,
            )
        )
    return Momentum(model, mapping, roots, timestep, scene, articulations) if roots else None
