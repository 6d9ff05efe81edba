"""MuJoCo's actuator force clamps on a DoF: each joint actuator's force clamped to its `forcerange`, their geared
sum to the joint's `actuatorfrcrange`. While a clamp binds, the clamped sum is a generalized force, the drive keeps
the joint's passive law and the kv MuJoCo still treats implicitly (the actuators no forcerange clamped), and that
kv's force at the current rate rides on the velocity target. Derivation: docs/mapping.md#actuators
(tests/test_loader_actuators.py::test_clamped_actuator_forces_match_mujoco)."""

from __future__ import annotations

import numpy as np

from .actuator_laws import ActuatorLaws
from .dof_step import DofKey, DofLayout, Step


class ForceClamps:
    """The DoFs MuJoCo can clamp: `member` (positions among the joint actuators) and `owner` (which clamped DoF
    each belongs to), per clamped DoF its drive column, joint position, range and passive law."""

    def __init__(self, limited: dict[DofKey, list[int]], joint_range: dict[DofKey, tuple[float, float]],
                 joint_actuators: list[int], layout: DofLayout, passive: np.ndarray):
        position = {a: i for i, a in enumerate(joint_actuators)}
        keys = list(limited)
        pairs = [(k, position[a]) for k, key in enumerate(keys) for a in limited[key]]
        self.owner = np.array([k for k, _ in pairs], dtype=int)
        self.member = np.array([i for _, i in pairs], dtype=int)
        self.count = len(keys)
        self.joint_count = len(joint_actuators)
        self.drive, self.flat = layout.drive_of(keys), layout.flat_of(keys)
        self.member_flat = self.flat[self.owner]
        self.low = np.array([joint_range.get(key, (-np.inf, np.inf))[0] for key in keys], dtype=np.float64)
        self.high = np.array([joint_range.get(key, (-np.inf, np.inf))[1] for key in keys], dtype=np.float64)
        self.passive = passive[:, self.drive]

    def binding(self, step: Step, joint: ActuatorLaws):
        """(binding DoFs, the clamped geared sum, the implicit kv) at this state, or None when nothing binds."""
        member = self.member
        gear = joint.gear[member]
        unclamped = joint.unclamped(step.inputs[joint.indices[member]], gear * step.q[self.member_flat],
                                    gear * step.v[self.member_flat], member)
        force = joint.clamped(unclamped, member)
        saturated = force != unclamped
        total = np.bincount(self.owner, gear * force, minlength=self.count)
        binding = (np.bincount(self.owner, saturated, minlength=self.count) > 0) | ~(
            (self.low <= total) & (total <= self.high))
        if not binding.any():
            return None
        implicit = np.where(saturated | step.explicit_kv, 0.0, joint.damping[member])
        implicit_kv = np.bincount(self.owner, implicit, minlength=self.count)
        return binding, np.minimum(np.maximum(total, self.low), self.high), implicit_kv

    def apply(self, found, step: Step) -> np.ndarray:
        """The binding DoFs' drives and forces; returns which joint actuators were clamped."""
        binding, total, implicit_kv = found
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
