"""Actuator forces every step: joint actuators join their DoF's drive, tendon actuators apply J^T f, and MuJoCo's
force clamps and its implicit/explicit split of kv decide what stays in the drive.

MuJoCo evaluates each actuator's force at the start of the step, clamps it to its `forcerange`, clamps the joint's
sum to the joint's `actuatorfrcrange`, and treats kv implicitly (implicitfast, implicit) only for the actuators its
forcerange did not clamp. On a step where a clamp binds, the clamped sum becomes a generalized force and the drive
keeps the joint's passive terms and the kv still implicit. Every law acts on arrays planned at load
(`compile`). Derivation: docs/mapping.md#actuators.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import mj
from ..build.actuators import SPATIAL, ActuatorMap, map_actuator
from ..build.mapping import Mapping
from ..drive import DofDrive
from ..errors import Notes
from .actuator_laws import ActuatorLaws
from .clamps import ForceClamps
from .dof_step import DofKey, DofLayout, Step
from .spatial_actuators import SpatialActuators
from .tendon_actuators import TendonActuators
from .tendons import COUPLED_DAMPING, IMPLICIT


@dataclass
class ActuatorTerm:
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
    paths: object = None  # those tendons' paths (`tendon_paths.TendonPaths`), set by the controller's plan
    name: str = "actuators"

    applied = property(lambda self: self.spatial.applied if getattr(self, "spatial", None) is not None else ())

    def compile(self, layout: DofLayout, passive: np.ndarray) -> None:
        """The arrays every step reads: the drive laws (rows stiffness, damping, constant, force limit), the joint
        actuators (`joint`, with their drive DoF `drive` and joint position `flat`), the clamps, the tendon
        actuators."""
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
        self.spatial = SpatialActuators(self.actuators, spatial, self.paths, self.implicit_tendon_kv) \
            if spatial and self.paths is not None else None
        if self.spatial is not None:
            self.spatial.compile(layout)
        self.idle = not len(self.joint) and self.tendons is None and self.spatial is None  # nothing mapped
        self.kv = np.bincount(self.drive, self.joint.damping, minlength=len(layout.keys))
        self.kv_dofs = np.flatnonzero(self.kv)

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
            if self.unique:
                constants = law[2]  # a row view: plain indexing is quicker than a 2-D one
                constants[drive] += constant
            else:
                np.add.at(law[2], drive, constant)
        if self.tendons is not None:
            self.tendons.contribute(step)
        if self.spatial is not None:
            self.spatial.contribute(step)
        if step.explicit_kv:
            self.explicit_kv(free, step)

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
            damping[dofs] = self.passive_law[1][dofs]
            flat = step.layout.flat[dofs]
            step.force[flat] += -kv[dofs] * step.v[flat]

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


def plan(model: mujoco.MjModel, mapping: Mapping, passive: dict[DofKey, DofDrive],
         notes: Notes) -> tuple[ActuatorTerm, list[ActuatorMap]]:
    """Every actuator's map (unmapped ones noted) and the term that applies the mapped ones every step."""
    term = ActuatorTerm([], passive)
    disabled = mj.disabled(model, "actuation")
    for a in range(model.nu):
        entry, terms = map_actuator(model, mapping, a, disabled)
        term.actuators.append(entry)
        if not entry.mapped:
            notes.drop("actuator", entry.name, entry.reason)
        elif terms is SPATIAL:
            term.spatial_tendons[a] = tendon = int(model.actuator_trnid[a][0])
            if entry.damping and len(mj.tendon_dofs(model, tendon)) > 1 and int(model.opt.integrator) in IMPLICIT:
                notes.approximate("actuator", entry.name, COUPLED_DAMPING)
        elif terms is not None:
            term.tendon_terms[a] = terms
            if entry.damping and len(terms) > 1 and int(model.opt.integrator) in IMPLICIT:
                notes.approximate("actuator", entry.name, COUPLED_DAMPING)
        else:  # a joint actuator joins its DoF's drive: gear^2 kp and kv on top of the passive terms
            key = (entry.articulation, entry.dofs[0])
            law = term.laws.setdefault(key, DofDrive(**vars(passive[key])))
            law.stiffness += entry.stiffness
            law.damping += entry.damping
    members: dict[DofKey, list[int]] = {}
    for a, entry in enumerate(term.actuators):
        if entry.mapped and entry.joint is not None:
            members.setdefault((entry.articulation, entry.dofs[0]), []).append(a)
    for j, target in enumerate(mapping.joints):  # <joint actuatorfrcrange>: MuJoCo clamps the joint's actuator sum
        key = (target.articulation, target.dofs[0]) if target.kind in ("hinge", "slide") else None
        if key in members and model.jnt_actfrclimited[j]:
            term.joint_range[key] = tuple(float(x) for x in model.jnt_actfrcrange[j])
    for key, indices in members.items():
        if key in term.joint_range or any(term.actuators[a].forcerange for a in indices):
            term.limited[key] = indices
    return term, term.actuators
