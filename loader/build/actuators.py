"""MuJoCo actuators as the loader maps them: one `ActuatorMap` per actuator, from the compiled model.

A fixed-gain, affine-bias actuator (motor, position, velocity, general PD) on a hinge or slide joint or a tendon
is mapped exactly; other dynamics, gains, biases and transmissions are listed as unsupported. The per-step
force law is `runtime/actuators.py`. Derivation: docs/mapping.md#actuators.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .. import mj
from ..runtime.activation import MAPPED as MAPPED_DYNAMICS
from ..runtime.tendon_paths import carried
from .fixed_tendons import fixed_tendon_terms
from .mapping import Mapping

TRN, DYN, GAIN, BIAS = mujoco.mjtTrn, mujoco.mjtDyn, mujoco.mjtGain, mujoco.mjtBias
SPATIAL: list = []  # the terms `map_actuator` gives an actuator on a spatial tendon (whose terms change with the pose)


@dataclass(frozen=True)
class ActuatorMap:
    """One MuJoCo actuator in SAPIEN. `stiffness` / `damping` are the joint-space gains it adds (gear² kp and
    gear² kv, MuJoCo's terms); the PhysX drive of a DoF sums them with the joint's passive terms and takes
    damping - stiffness x timestep as its damping (`drive.py`)."""

    name: str
    kind: str  # "motor", "position", "velocity", "general"
    joint: str | None
    tendon: str | None
    articulation: int | None
    dofs: tuple[int, ...]
    gear: float
    ctrlrange: tuple[float, float] | None
    forcerange: tuple[float, float] | None
    stiffness: float = 0.0
    damping: float = 0.0
    # MuJoCo's force law in actuator space: gain * ctrl + bias[0] + bias[1] * length + bias[2] * velocity
    gain: float = 0.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mapped: bool = True
    reason: str = ""
    dynamics: str = "none"  # "filter", "filterexact", "integrator": the gain multiplies the activation

    def unclamped(self, ctrl: float, length: float, velocity: float) -> float:
        """MuJoCo's actuator force law (before gear and before the forcerange clamp)."""
        return float(self.gain * ctrl + self.bias[0] + self.bias[1] * length + self.bias[2] * velocity)

    def force(self, ctrl: float, length: float, velocity: float) -> float:
        """The actuator force (before gear) this mapping applies, clamped to forcerange."""
        force = self.unclamped(ctrl, length, velocity)
        return min(max(force, self.forcerange[0]), self.forcerange[1]) if self.forcerange is not None else force


def _kind(model: mujoco.MjModel, a: int) -> str:
    bias = model.actuator_biasprm[a]
    if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_NONE) or not np.any(bias[:3]):
        return "motor"
    if bias[1] != 0:
        return "position"
    return "velocity" if bias[2] != 0 else "general"


def map_actuator(model: mujoco.MjModel, mapping: Mapping, a: int,
                 disabled: bool) -> tuple[ActuatorMap, list[tuple[int, int, float]] | None]:
    """Actuator `a` in SAPIEN, with its tendon's (articulation, dof, coefficient) terms for a tendon actuator."""
    name = mj.name(model, "actuator", a)
    gear = float(model.actuator_gear[a][0])
    ctrlrange = tuple(float(x) for x in model.actuator_ctrlrange[a]) if model.actuator_ctrllimited[a] else None
    forcerange = tuple(float(x) for x in model.actuator_forcerange[a]) if model.actuator_forcelimited[a] else None
    trn = int(model.actuator_trntype[a])
    target = int(model.actuator_trnid[a][0])
    base = {"name": name, "kind": _kind(model, a), "joint": None, "tendon": None, "articulation": None, "dofs": (),
            "gear": gear, "ctrlrange": ctrlrange, "forcerange": forcerange}
    if disabled:
        return ActuatorMap(**base, mapped=False, reason="actuation disabled by the model's <flag actuation>"), None
    dyntype = int(model.actuator_dyntype[a])
    if dyntype != int(DYN.mjDYN_NONE) and dyntype not in MAPPED_DYNAMICS:
        dyn = DYN(dyntype).name.removeprefix("mjDYN_").lower()
        return ActuatorMap(**base, mapped=False, reason=f"activation dynamics ({dyn}) are not mapped"), None
    if int(model.actuator_gaintype[a]) != int(GAIN.mjGAIN_FIXED) or int(model.actuator_biastype[a]) not in (
            int(BIAS.mjBIAS_NONE), int(BIAS.mjBIAS_AFFINE)):
        return ActuatorMap(**base, mapped=False, reason="gain or bias is not affine (muscle or user)"), None
    bias = model.actuator_biasprm[a] if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_AFFINE) else np.zeros(3)
    base["gain"] = float(model.actuator_gainprm[a][0])
    base["dynamics"] = MAPPED_DYNAMICS.get(dyntype, "none")
    base["bias"] = (float(bias[0]), float(bias[1]), float(bias[2]))
    if trn == int(TRN.mjTRN_JOINT):
        joint = mapping.joints[target]
        if joint.kind not in ("hinge", "slide"):
            return ActuatorMap(**base, mapped=False, reason=f"drives a {joint.kind} joint"), None
        stiffness, damping = -bias[1] * gear**2, -bias[2] * gear**2
        base.update(joint=mj.name(model, "joint", target), articulation=joint.articulation,
                    dofs=joint.dofs)
        return ActuatorMap(**base, stiffness=float(stiffness), damping=float(damping)), None
    if trn == int(TRN.mjTRN_TENDON):
        terms = fixed_tendon_terms(model, target)
        if not terms:  # a spatial tendon: its path and Jacobian are MuJoCo's at every step (`runtime/tendon_paths.py`)
            if not carried(model, mapping, target):
                return ActuatorMap(**base, mapped=False, reason="its spatial tendon crosses a ball joint"), None
            joints = [mapping.joints[int(model.dof_jntid[d])] for d in sorted(mj.tendon_dofs(model, target))]
            hinges = [j for j in joints if j.kind in ("hinge", "slide")]
            base.update(tendon=mj.name(model, "tendon", target), dofs=tuple(j.dofs[0] for j in hinges),
                        articulation=hinges[0].articulation if hinges else None)
            return ActuatorMap(**base, stiffness=float(-bias[1] * gear**2),
                               damping=float(-bias[2] * gear**2)), SPATIAL
        mapped_terms = []
        for joint_id, coefficient in terms:
            joint = mapping.joints[joint_id]
            if joint.kind not in ("hinge", "slide"):
                return ActuatorMap(**base, mapped=False, reason="its tendon crosses a ball or free joint"), None
            mapped_terms.append((joint.articulation, joint.dofs[0], coefficient))
        base.update(tendon=mj.name(model, "tendon", target),
                    articulation=mapped_terms[0][0], dofs=tuple(d for _, d, _ in mapped_terms))
        return ActuatorMap(**base, stiffness=float(-bias[1] * gear**2), damping=float(-bias[2] * gear**2)), mapped_terms
    kind = TRN(trn).name.removeprefix("mjTRN_").lower()
    return ActuatorMap(**base, mapped=False, reason=f"{kind} transmission is not mapped"), None
