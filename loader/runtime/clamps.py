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
    each belongs to) with the members' gear, bias and forcerange; per clamped DoF its drive column, joint position,
    range and passive law. `single`: every clamped DoF has one actuator (no sums); `ranged`: some DoF has an
    actuatorfrcrange."""

    def __init__(self, limited: dict[DofKey, list[int]], joint_range: dict[DofKey, tuple[float, float]],
                 joint: ActuatorLaws, layout: DofLayout, passive: np.ndarray):
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
        unclamped = (affine[self.member] + self.length_bias * (gear * step.q[flat])
                     + self.velocity_bias * (gear * step.v[flat]))
        force = np.minimum(np.maximum(unclamped, self.force_low), self.force_high)
        saturated = force != unclamped
        total = gear * force
        if self.single:
            binding = saturated
        else:
            total = np.bincount(self.owner, total, minlength=self.count)
            binding = np.bincount(self.owner, saturated, minlength=self.count) > 0
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
