"""Actuator forces every step: joint actuators join their DoF's drive, tendon actuators apply J^T f, and MuJoCo's
force clamps and its implicit/explicit split of kv decide what stays in the drive.

MuJoCo evaluates each actuator's force at the start of the step, clamps it to its `forcerange`, clamps the joint's
sum to the joint's `actuatorfrcrange`, and treats kv implicitly (implicitfast, implicit) only for the actuators its
forcerange did not clamp. On a step where a clamp binds, the clamped sum becomes a generalized force and the drive
keeps the joint's passive terms and the kv still implicit. Derivation: docs/mapping.md#actuators.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import mujoco

from .. import mj
from ..build.actuators import ActuatorMap, map_actuator
from ..build.mapping import Mapping
from ..drive import DofDrive
from ..errors import Notes
from .dof_step import DofKey, Step
from .tendons import tendon_state


@dataclass
class ActuatorTerm:
    """The mapped actuators' per-step law. `laws`: the drive law of each DoF with joint actuators (its passive
    spring-damper plus their gear^2 kp and kv), what the drive carries while no clamp binds."""

    actuators: list[ActuatorMap]
    passive: dict[DofKey, DofDrive]
    laws: dict[DofKey, DofDrive] = field(default_factory=dict)
    tendon_terms: dict[int, list[tuple[int, int, float]]] = field(default_factory=dict)  # actuator -> (a, dof, c)
    limited: dict[DofKey, list[int]] = field(default_factory=dict)  # DoFs MuJoCo can clamp -> joint actuators
    joint_range: dict[DofKey, tuple[float, float]] = field(default_factory=dict)  # actuatorfrcrange
    name: str = "actuators"

    def contribute(self, step: Step) -> None:
        for key, law in self.laws.items():
            step.dofs[key].law, step.dofs[key].constant = law, law.constant
        clamped: set[int] = set()  # joint actuators applied explicitly this step
        for key, members in self.limited.items():
            found = self.clamped_step(key, members, step)
            if found is not None:
                record = step.dofs[key]
                record.law, record.constant, force, record.via_damping = found
                step.add(key, force)
                clamped.update(members)
        inputs = step.inputs
        for a, actuator in enumerate(self.actuators):
            if not actuator.mapped or a in clamped:
                continue
            if actuator.joint is not None:
                step.dofs[(actuator.articulation, actuator.dofs[0])].constant += actuator.gear * (
                    actuator.gain * inputs[a] + actuator.bias[0])
                continue
            self.tendon_actuator(a, actuator, step)
        self.explicit_kv(clamped, step)

    def tendon_actuator(self, a: int, actuator: ActuatorMap, step: Step) -> None:
        """J^T f of a fixed tendon's actuator, its bias from the state now. MuJoCo's implicit step holds only the
        diagonal of kv J^T J (none once its forcerange clamps it): that joins the drives, and the explicit force
        gets it back at the current rate."""
        terms = self.tendon_terms[a]
        length, speed = (actuator.gear * x for x in tendon_state(terms, step.q, step.v))
        force = actuator.force(step.inputs[a], length, speed)
        saturated = force != actuator.unclamped(step.inputs[a], length, speed)
        implicit = 0.0 if step.explicit_kv else self.implicit_tendon_kv(actuator, saturated)
        for art, dof, c in terms:
            step.forces[art][dof] += actuator.gear * c * force + implicit * c * c * step.v[art][dof]
            step.dofs[(art, dof)].implicit_extra += implicit * c * c

    def explicit_kv(self, clamped: set[int], step: Step) -> None:
        """Under Euler (and RK4) joint actuators' kv leaves the drive as the explicit force -kv qdot; the drive keeps
        the passive damping itself (not a difference, whose rounding would move the kp dt boundary of
        `stiffness.py`)."""
        kv: dict[DofKey, float] = {}
        for a, actuator in enumerate(self.actuators):
            if actuator.mapped and actuator.joint is not None and a not in clamped:
                key = (actuator.articulation, actuator.dofs[0])
                kv[key] = kv.get(key, 0.0) + (actuator.damping if step.explicit_kv else 0.0)
        for key, damping in kv.items():
            if damping:
                record = step.dofs[key]
                record.law = dataclasses.replace(record.law, damping=self.passive[key].damping)
                step.add(key, -damping * step.v[key[0]][key[1]])

    def clamped_step(self, key: DofKey, members: list[int], step: Step):
        """MuJoCo's actuator force on one DoF when a clamp binds at this state: (drive, constant, clamped actuator
        force, kv qdot of the actuators MuJoCo still treats implicitly), or None when nothing clamps."""
        q, v = step.q[key[0]][key[1]], step.v[key[0]][key[1]]
        total, binding, implicit_kv = 0.0, False, 0.0
        for a in members:
            actuator = self.actuators[a]
            gear = actuator.gear
            force = actuator.force(step.inputs[a], gear * q, gear * v)
            if force != actuator.unclamped(step.inputs[a], gear * q, gear * v):
                binding = True
            elif not step.explicit_kv:
                implicit_kv += actuator.damping
            total += gear * force
        if key in self.joint_range:
            low, high = self.joint_range[key]
            binding = binding or not low <= total <= high
            total = min(max(total, low), high)
        if not binding:
            return None
        passive = self.passive[key]
        drive_now = DofDrive(passive.stiffness, passive.damping + implicit_kv, passive.constant)
        return drive_now, passive.constant, total, implicit_kv * v

    @staticmethod
    def implicit_tendon_kv(actuator: ActuatorMap, saturated: bool) -> float:
        """A tendon actuator's joint-space kv (gear^2 kv) that MuJoCo's implicit step treats implicitly: none once
        its forcerange clamps it (as for joint actuators)."""
        return 0.0 if saturated else actuator.damping

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
        elif terms is not None:
            term.tendon_terms[a] = terms
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
