"""Passive fixed tendons: their spring and damper forces, applied every step as MuJoCo applies them."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .. import mj
from ..build.fixed_tendons import fixed_tendon_terms


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


IMPLICIT = (int(mujoco.mjtIntegrator.mjINT_IMPLICIT), int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST))
COUPLED_DAMPING = ("damping implicit in its diagonal b J_i^2 only (MuJoCo's implicit integrators hold the whole "
                   "b J^T J; the off-diagonal part is explicit)")


def map_tendons(model: mujoco.MjModel, mapping, notes) -> list[PassiveTendon]:
    """Passive tendon properties: a fixed tendon's spring and damper, applied as MuJoCo does (`PassiveTendon`;
    Euler takes the damper explicitly). A PhysX fixed tendon would be implicit in its spring too
    (tests/test_loader_passive.py::test_a_passive_fixed_tendon_matches_mujoco)."""
    out, passive = [], mj.tendon_passive(model)
    for t in range(model.ntendon):
        name = mj.name(model, "tendon", t)
        terms = fixed_tendon_terms(model, t)
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
            if target.kind not in ("hinge", "slide"):
                notes.drop("tendon", name, "crosses a ball or free joint")
                break
            mapped.append((target.articulation, target.dofs[0], coefficient))
        else:
            if damping and len(mapped) > 1 and int(model.opt.integrator) in IMPLICIT:
                notes.approximate("tendon", name, COUPLED_DAMPING)
            low, high = (float(x) for x in model.tendon_lengthspring[t])
            out.append(PassiveTendon(name, tuple(mapped), stiffness, damping, low, high))
    return out


class TendonTerm:
    """The passive fixed tendons' forces every step, as arrays over their terms (per term its tendon `owner`,
    joint position `flat`, drive column and coefficient), and the spatial ones' (`spatial`); under implicit
    integrators their dampers' diagonal joins the drives (`Step.implicit_extra`)."""

    name = "tendons"

    def __init__(self, tendons: list[PassiveTendon], spatial=None):
        self.tendons, self.spatial = tendons, spatial

    applied = property(lambda self: self.spatial.applied if self.spatial is not None else ())  # root wrenches

    def compile(self, layout) -> None:
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
