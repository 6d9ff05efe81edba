"""Actuator forces every step: joint actuators join their DoF's drive, tendon actuators apply J^T f, and MuJoCo's
force clamps and its implicit/explicit split of kv decide what stays in the drive.

MuJoCo evaluates each actuator's force at the start of the step, clamps it to its `forcerange`, clamps the joint's
sum to the joint's `actuatorfrcrange`, and treats kv implicitly (implicitfast, implicit) only for the actuators its
forcerange did not clamp. On a step where a clamp binds, the clamped sum becomes a generalized force and the drive
keeps the joint's passive terms and the kv still implicit. Tendon actuators apply J^T f with f MuJoCo's force at
the tendon's length and rate now (a spatial tendon's along its path, `tendons.py`); implicitfast holds their whole
kv J^T J implicitly (none once a forcerange clamps it), of which the drives take the diagonal. Every law acts on
arrays planned at load (`compile`). Derivation: docs/mapping.md#actuators
(tests/test_loader_actuators.py::test_clamped_actuator_forces_match_mujoco,
tests/test_loader_actuators.py::test_a_tendon_servo_matches_mujoco,
tests/test_loader_spatial_tendons.py::test_a_spatial_tendon_servo_matches_mujoco).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import Notes
from ..model import mj
from ..model.actuators import MOMENT, SPATIAL, ActuatorMap
from ..model.drive import DofDrive
from ..model.mapping import Mapping
from .dof_step import DofKey, DofLayout, Step
from .tendons import COUPLED_DAMPING, AlongPaths, TendonPaths
from .term import Compilation, Term
from .transmissions import MuscleActuators


class ActuatorLaws:
    """Columns of actuator parameters, one per actuator of `indices` (MuJoCo's actuator ids)."""

    def __init__(self, actuators: list[ActuatorMap], indices: list[int]):
        chosen = [actuators[a] for a in indices]
        self.indices = np.array(indices, dtype=int)
        self.gear = np.array([x.gear for x in chosen], dtype=np.float64)
        self.gain = np.array([x.gain for x in chosen], dtype=np.float64)
        self.bias = np.array([x.bias for x in chosen], dtype=np.float64).reshape(-1, 3).T.copy()
        self.low = np.array([x.forcerange[0] if x.forcerange else -np.inf for x in chosen], dtype=np.float64)
        self.high = np.array([x.forcerange[1] if x.forcerange else np.inf for x in chosen], dtype=np.float64)
        self.damping = np.array([x.damping for x in chosen], dtype=np.float64)  # gear^2 kv

    def __len__(self) -> int:
        return int(self.indices.size)

    def unclamped(self, inputs: np.ndarray, length: np.ndarray, velocity: np.ndarray, chosen=slice(None)):
        """MuJoCo's force law (before gear and clamp) of the `chosen` actuators."""
        bias = self.bias
        return self.gain[chosen] * inputs + bias[0][chosen] + bias[1][chosen] * length + bias[2][chosen] * velocity

    def clamped(self, unclamped: np.ndarray, chosen=slice(None)) -> np.ndarray:
        """The force clamped to forcerange (no range: unchanged)."""
        return np.minimum(np.maximum(unclamped, self.low[chosen]), self.high[chosen])


class ForceClamps:
    """The DoFs MuJoCo can clamp: `member` (positions among the joint actuators) and `owner` (which clamped DoF
    each belongs to) with the members' gear, bias and forcerange; per clamped DoF its drive column, joint position,
    range and passive law. `single`: every clamped DoF has one actuator (no sums); `ranged`: some DoF has an
    actuatorfrcrange."""

    def __init__(
        self,
        limited: dict[DofKey, list[int]],
        joint_range: dict[DofKey, tuple[float, float]],
        joint: ActuatorLaws,
        layout: DofLayout,
        passive: np.ndarray,
    ):
        position = {int(a): i for i, a in enumerate(joint.indices)}
        keys = list(limited)
        pairs = [(k, position[a]) for k, key in enumerate(keys) for a in limited[key]]
        self.owner = np.array([k for k, _ in pairs], dtype=int)
        self.member = np.array([i for _, i in pairs], dtype=int)
        self.count, self.joint_count = len(keys), len(joint)
        self.single = self.owner.size == self.count
        self.drive, self.flat = layout.drive_of(keys), layout.flat_of(keys)
        self.member_flat = self.flat[self.owner]
        self.low = np.array([joint_range.get(key, (-np.inf, np.inf))[0] for key in keys], dtype=np.float64)
        self.high = np.array([joint_range.get(key, (-np.inf, np.inf))[1] for key in keys], dtype=np.float64)
        self.ranged = bool(joint_range)
        member = self.member
        self.gear, self.damping = joint.gear[member], joint.damping[member]
        self.length_bias, self.velocity_bias = joint.bias[1][member], joint.bias[2][member]
        self.force_low, self.force_high = joint.low[member], joint.high[member]
        self.passive = passive[:, self.drive]

    def binding(self, step: Step, affine: np.ndarray):
        """(binding DoFs, the clamped geared sum, the implicit kv) at this state, or None when nothing binds.
        `affine`: gain x input + bias0 of every joint actuator."""
        gear, flat = self.gear, self.member_flat
        unclamped = (
            affine[..., self.member]
            + self.length_bias * (gear * step.q[..., flat])
            + self.velocity_bias * (gear * step.v[..., flat])
        )
        force = np.minimum(np.maximum(unclamped, self.force_low), self.force_high)
        saturated = force != unclamped
        total = gear * force
        if self.single:
            binding = saturated
        elif total.ndim == 1:
            total = np.bincount(self.owner, total, minlength=self.count)
            binding = np.bincount(self.owner, saturated, minlength=self.count) > 0
        else:  # a batch's copies: only whether anything binds is read (`ActuatorTerm.batch`)
            sums = np.zeros((*total.shape[:-1], self.count))
            np.add.at(sums.T, self.owner, total.T)
            binding = np.zeros(sums.shape, dtype=bool)
            np.logical_or.at(binding.T, self.owner, saturated.T)
            total = sums
        if self.ranged:
            binding = binding | ~((self.low <= total) & (total <= self.high))
        if not np.count_nonzero(binding):
            return None
        implicit = np.where(saturated | step.explicit_kv, 0.0, self.damping)
        implicit_kv = implicit if self.single else np.bincount(self.owner, implicit, minlength=self.count)
        return binding, np.minimum(np.maximum(total, self.low), self.high), implicit_kv

    def apply(self, found, step: Step) -> np.ndarray:
        """The binding DoFs' drives and forces; returns which joint actuators were clamped."""
        binding, total, implicit_kv = found
        step.regular = False
        drive, flat, passive = self.drive[binding], self.flat[binding], self.passive[:, binding]
        law = step.law
        law[0, drive] = passive[0]
        law[1, drive] = passive[1] + implicit_kv[binding]
        law[2, drive] = passive[2]
        law[3, drive] = np.inf
        law[4, drive] = implicit_kv[binding] * step.v[flat]
        step.force[flat] += total[binding]
        clamped = np.zeros(self.joint_count, dtype=bool)
        clamped[self.member[binding[self.owner]]] = True
        return clamped


class TendonActuators:
    """The mapped tendon actuators (`laws`) and their tendons' terms: per term its actuator (`owner`), joint
    position (`flat`), drive column and coefficient, and the implicit diagonal kv c^2 while no forcerange
    clamps (`diagonal`)."""

    def __init__(
        self,
        actuators: list[ActuatorMap],
        terms: dict[int, list[tuple[int, int, float]]],
        layout: DofLayout,
        implicit_kv,
    ):
        order = list(terms)
        self.laws = ActuatorLaws(actuators, order)
        rows = [(k, (art, dof), c) for k, a in enumerate(order) for art, dof, c in terms[a]]
        self.owner = np.array([k for k, _, _ in rows], dtype=int)
        self.flat = layout.flat_of([key for _, key, _ in rows])
        self.drive = layout.drive_of([key for _, key, _ in rows])
        self.coefficient = np.array([c for _, _, c in rows], dtype=np.float64)
        self.geared = self.laws.gear[self.owner] * self.coefficient  # gear c per term
        self.implicit_kv = implicit_kv  # (damping, saturated) -> the kv MuJoCo's implicit step keeps
        c, count = self.coefficient, len(self.laws)
        self.diagonal = (np.zeros(count) + implicit_kv(self.laws.damping, np.zeros(count, bool)))[self.owner] * c * c
        self.unique = len(set(self.flat.tolist())) == self.flat.size  # no DoF in two terms: no sums

    def contribute(self, step: Step) -> None:
        laws, owner, c, count = self.laws, self.owner, self.coefficient, len(self.laws)
        q, v = step.q[self.flat], step.v[self.flat]
        length = laws.gear * np.bincount(owner, c * q, minlength=count)
        speed = laws.gear * np.bincount(owner, c * v, minlength=count)
        unclamped = laws.unclamped(step.inputs[laws.indices], length, speed)
        force = laws.clamped(unclamped)
        saturated = force != unclamped
        clamped = bool(np.count_nonzero(saturated))
        if clamped:
            step.regular = False
        if step.explicit_kv:
            diagonal = None  # kv explicit: nothing joins the drives
        elif clamped:
            diagonal = (np.zeros(count) + self.implicit_kv(laws.damping, saturated))[owner] * c * c
        else:
            diagonal = self.diagonal
        term_force = self.geared * force[owner]
        if diagonal is not None:
            term_force += diagonal * v
        if self.unique:
            step.force[self.flat] += term_force
            if diagonal is not None:
                extra = step.law[5]
                extra[self.drive] += diagonal
        else:
            np.add.at(step.force, self.flat, term_force)
            if diagonal is not None:
                np.add.at(step.law[5], self.drive, diagonal)


class SpatialActuators(AlongPaths):
    """The mapped actuators on spatial tendons (`tendons`: actuator id -> tendon id) along `paths`."""

    def __init__(self, actuators: list[ActuatorMap], tendons: dict[int, int], paths: TendonPaths, implicit_kv):
        order = list(tendons)
        super().__init__(paths, [tendons[a] for a in order])
        self.laws = ActuatorLaws(actuators, order)
        self.implicit_kv = implicit_kv  # (damping, saturated) -> the kv MuJoCo's implicit step keeps
        self.damped = bool(self.laws.damping.any())

    def contribute(self, step: Step) -> None:
        laws = self.laws
        length, jacobian, v = self.paths.state(step)
        jacobian = jacobian[self.rows]
        unclamped = laws.unclamped(step.inputs[laws.indices], laws.gear * length[self.rows], laws.gear * (jacobian @ v))
        force = laws.clamped(unclamped)
        saturated = force != unclamped
        if saturated.any():
            step.regular = False
        implicit = None
        if self.damped and not step.explicit_kv:
            implicit = self.implicit_kv(laws.damping, saturated)  # gear^2 kv per actuator, none once clamped
        self.paths.apply(step, jacobian.T @ (laws.gear * force), self.push, jacobian, v, implicit)


@dataclass
class ActuatorTerm(Term):
    """The mapped actuators' per-step law. `laws`: the drive law of each DoF with joint actuators (its passive
    spring-damper plus their gear^2 kp and kv), what the drive carries while no clamp binds. `compile` turns the
    plan into arrays; edits to the plan take effect at the next `compile` (the controller's, after it hands out a
    term or the laws)."""

    actuators: list[ActuatorMap]
    passive: dict[DofKey, DofDrive]
    laws: dict[DofKey, DofDrive] = field(default_factory=dict)
    tendon_terms: dict[int, list[tuple[int, int, float]]] = field(default_factory=dict)  # actuator -> (a, dof, c)
    limited: dict[DofKey, list[int]] = field(default_factory=dict)  # DoFs MuJoCo can clamp -> joint actuators
    joint_range: dict[DofKey, tuple[float, float]] = field(default_factory=dict)  # actuatorfrcrange
    spatial_tendons: dict[int, int] = field(default_factory=dict)  # actuator -> its spatial tendon
    paths: TendonPaths | None = None  # those tendons' paths (`tendons.TendonPaths`)
    spatial: SpatialActuators | None = field(default=None, init=False, repr=False)  # `compile`'s
    moment_actuators: list[int] = field(default_factory=list)  # actuators whose moment MuJoCo computes
    moments: TendonPaths | None = None  # their paths (`transmissions.MomentPaths`)
    moment: SpatialActuators | None = field(default=None, init=False, repr=False)  # `compile`'s
    muscles: MuscleActuators | None = field(default=None, init=False, repr=False)  # `compile`'s

    name = "actuators"

    @property
    def applied(self) -> list | tuple:
        alongs = (self.spatial, self.moment, self.muscles)
        return [wrench for along in alongs if along is not None for wrench in along.applied]

    def compile(self, compilation: Compilation) -> None:
        """The arrays every step reads: the drive laws (rows stiffness, damping, constant, force limit), the joint
        actuators (`joint`, with their drive DoF `drive` and joint position `flat`), the clamps, the tendon
        actuators."""
        layout, passive = compilation.layout, compilation.passive
        self.base = passive.copy()
        for key, law in self.laws.items():
            self.base[:, layout.index[key]] = (law.stiffness, law.damping, law.constant, law.force_limit)
        self.passive_law = passive
        indices = [a for a, x in enumerate(self.actuators) if x.mapped and x.joint is not None]
        self.joint = ActuatorLaws(self.actuators, indices)
        keys = [(self.actuators[a].articulation, self.actuators[a].dofs[0]) for a in indices]
        self.drive, self.flat = layout.drive_of(keys), layout.flat_of(keys)
        self.clamps = ForceClamps(self.limited, self.joint_range, self.joint, layout, passive) if self.limited else None
        self.unique = len(set(self.drive.tolist())) == self.drive.size  # one joint actuator per DoF
        mapped = {a: terms for a, terms in self.tendon_terms.items() if self.actuators[a].mapped}
        self.tendons = TendonActuators(self.actuators, mapped, layout, self.implicit_tendon_kv) if mapped else None
        spatial = {a: t for a, t in self.spatial_tendons.items() if self.actuators[a].mapped}
        self.spatial = (
            SpatialActuators(self.actuators, spatial, self.paths, self.implicit_tendon_kv)
            if spatial and self.paths is not None
            else None
        )
        mapped = [a for a in self.moment_actuators if self.actuators[a].mapped]
        moment = [a for a in mapped if not self.actuators[a].muscle]
        muscles = [a for a in mapped if self.actuators[a].muscle]
        self.moment = (
            SpatialActuators(self.actuators, {a: a for a in moment}, self.moments, self.implicit_tendon_kv)
            if moment and self.moments is not None
            else None
        )  # MuJoCo's actuator rows in place of tendon rows
        self.muscles = (
            MuscleActuators(self.moments.model, muscles, self.moments, self.implicit_tendon_kv) if muscles else None
        )
        alongs = (self.spatial, self.moment, self.muscles)
        for along in alongs:
            if along is not None:
                along.compile(layout)
        self.idle = not len(self.joint) and self.tendons is None and all(along is None for along in alongs)
        self.kv = np.bincount(self.drive, self.joint.damping, minlength=len(layout.keys))
        self.kv_dofs = np.flatnonzero(self.kv)

    def batch(self, step: Step, steps: list[Step], terms: list[Term]) -> bool:
        """Every copy at once where only joint actuators act and no clamp binds in any copy."""
        if self.tendons is not None or any(along is not None for along in (self.spatial, self.moment, self.muscles)):
            return False
        joint = self.joint
        affine = joint.gain * step.inputs[..., joint.indices] + joint.bias[0] if len(joint) else None
        if affine is not None and self.clamped_step(step, affine) is not None:
            return False
        step.law[:4] = self.base[:, None]
        if affine is not None:
            self.add_constants(step.law[2], self.drive, joint.gear * affine)
        if step.explicit_kv:
            self.explicit_kv(None, step)
        return True

    def add_constants(self, constants: np.ndarray, drive: np.ndarray, constant: np.ndarray) -> None:
        """The joint actuators' constant part (gear x (gain x input + bias0)) into their drives' constants."""
        if self.unique:
            constants[..., drive] += constant
        else:
            np.add.at(constants.T, drive, constant.T)

    def contribute(self, step: Step) -> None:
        law = step.law
        law[:4] = self.base
        joint, free = self.joint, None
        if len(joint):
            affine = joint.gain * step.inputs[joint.indices] + joint.bias[0]
            found = self.clamped_step(step, affine)
            drive, constant = self.drive, joint.gear * affine
            if found is not None:
                free = ~self.clamps.apply(found, step)  # joint actuators not clamped
                drive, constant = drive[free], constant[free]
            self.add_constants(law[2], drive, constant)
        if self.tendons is not None:
            self.tendons.contribute(step)
        if self.spatial is not None:
            self.spatial.contribute(step)
        for along in (self.moment, self.muscles):
            if along is not None:
                along.contribute(step)
        if step.explicit_kv:
            self.explicit_kv(free, step)

    def contacts(self, enabled: bool) -> None:
        """A body transmission's moment reads MuJoCo's contacts, which its copy makes only while SAPIEN has them."""
        if self.moments is not None:
            self.moments.contacts(enabled)

    def clamped_step(self, step: Step, affine: np.ndarray):
        """MuJoCo's clamps at this state (`clamps.py`), or None when none binds. `affine`: gain x input + bias0 of
        every joint actuator."""
        return self.clamps.binding(step, affine) if self.clamps is not None else None

    def explicit_kv(self, free, step: Step) -> None:
        """Under Euler (and RK4) joint actuators' kv leaves the drive as the explicit force -kv qdot; the drive keeps
        the passive damping itself (not a difference, whose rounding would move the kp dt boundary of
        `stiffness.py`)."""
        if free is None:
            kv, dofs = self.kv, self.kv_dofs
        else:
            kv = np.bincount(self.drive[free], self.joint.damping[free], minlength=self.kv.size)
            dofs = np.flatnonzero(kv)
        if dofs.size:
            damping = step.law[1]
            damping[..., dofs] = self.passive_law[1][dofs]
            flat = step.layout.flat[dofs]
            step.force[..., flat] += -kv[dofs] * step.v[..., flat]

    @staticmethod
    def implicit_tendon_kv(damping: np.ndarray, saturated: np.ndarray):
        """Tendon actuators' joint-space kv (gear^2 kv) that MuJoCo's implicit step treats implicitly: none once
        a forcerange clamps it (as for joint actuators)."""
        return np.where(saturated, 0.0, damping)

    def tendon_kv_diagonal(self) -> dict[DofKey, float]:
        """The diagonal of tendon actuators' kv J^T J per DoF (what joins the drives under implicit integrators)."""
        out: dict[DofKey, float] = {}
        for a, terms in self.tendon_terms.items():
            for art, dof, c in terms:
                out[(art, dof)] = out.get((art, dof), 0.0) + self.actuators[a].damping * c * c
        return out


def plan_actuators(
    model: mujoco.MjModel,
    mapping: Mapping,
    passive: dict[DofKey, DofDrive],
    maps: list[tuple[ActuatorMap, list | None]],
    implicit: bool,
    notes: Notes,
) -> ActuatorTerm:
    """The term that applies the mapped actuators every step, from the plan's maps (each with its tendon's terms,
    `SPATIAL` for a spatial tendon, None for a joint actuator); `implicit`: MuJoCo's integrator is implicit."""
    term = ActuatorTerm([entry for entry, _ in maps], passive)
    for a, (entry, terms) in enumerate(maps):
        if not entry.mapped:
            continue
        if terms is SPATIAL:
            term.spatial_tendons[a] = tendon = int(model.actuator_trnid[a][0])
            if entry.damping and len(mj.tendon_dofs(model, tendon)) > 1 and implicit:
                notes.approximate("actuator", entry.name, COUPLED_DAMPING)
        elif terms is MOMENT:
            term.moment_actuators.append(a)
            if (entry.damping or entry.muscle) and len(mj.transmission_dofs(model, a)) > 1 and implicit:
                notes.approximate("actuator", entry.name, COUPLED_DAMPING)
        elif terms is not None:
            term.tendon_terms[a] = terms
            if entry.damping and len(terms) > 1 and implicit:
                notes.approximate("actuator", entry.name, COUPLED_DAMPING)
        else:  # a joint actuator joins its DoF's drive: gear^2 kp and kv on top of the passive terms
            key = (entry.articulation, entry.dofs[0])
            law = term.laws.setdefault(key, DofDrive(**vars(passive[key])))
            law.stiffness += entry.stiffness
            law.damping += entry.damping
    _plan_clamps(model, mapping, term)
    return term


def _plan_clamps(model: mujoco.MjModel, mapping: Mapping, term: ActuatorTerm) -> None:
    """The DoFs MuJoCo can clamp (`term.limited`: a joint actuator with a forcerange, or a joint with an
    actuatorfrcrange, whose range goes into `term.joint_range`)."""
    members: dict[DofKey, list[int]] = {}
    for a, entry in enumerate(term.actuators):
        if entry.mapped and entry.joint is not None:
            members.setdefault((entry.articulation, entry.dofs[0]), []).append(a)
    for j, target in enumerate(mapping.joints):  # <joint actuatorfrcrange>: MuJoCo clamps the joint's actuator sum
        key = target.drive_key
        if key in members and model.jnt_actfrclimited[j]:
            term.joint_range[key] = tuple(float(x) for x in model.jnt_actfrcrange[j])
    for key, indices in members.items():
        if key in term.joint_range or any(term.actuators[a].forcerange for a in indices):
            term.limited[key] = indices
