"""MuJoCo actuators as the loader maps them: one `ActuatorMap` per actuator, from the compiled model.

A fixed-gain, affine-bias actuator (motor, position, velocity, general PD) on a hinge or slide joint, a tendon, a
site, a slider-crank, a body (adhesion) or a free joint is mapped exactly; other dynamics, gains, biases and
transmissions (one across a ball joint) are listed as unsupported. The per-step
force law is `runtime/actuators.py`. Derivation: docs/mapping.md#actuators.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from ..model.actuators import MAPPED_DYNAMICS, MOMENT, SPATIAL, ActuatorMap
from ..model.joints import DRIVEN
from ..model.mapping import CARRIED, Mapping

TRN, DYN, GAIN, BIAS = mujoco.mjtTrn, mujoco.mjtDyn, mujoco.mjtGain, mujoco.mjtBias


def _kind(model: mujoco.MjModel, a: int) -> str:
    bias = model.actuator_biasprm[a]
    if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_NONE) or not np.any(bias[:3]):
        return "motor"
    if bias[1] != 0:
        return "position"
    return "velocity" if bias[2] != 0 else "general"


def map_actuator(
    model: mujoco.MjModel, mapping: Mapping, a: int, disabled: bool
) -> tuple[ActuatorMap, list[tuple[int, int, float]] | None]:
    """Actuator `a` in SAPIEN, with its tendon's (articulation, dof, coefficient) terms for a tendon actuator."""
    name = mj.name(model, "actuator", a)
    gear = float(model.actuator_gear[a][0])
    ctrlrange = tuple(float(x) for x in model.actuator_ctrlrange[a]) if model.actuator_ctrllimited[a] else None
    forcerange = tuple(float(x) for x in model.actuator_forcerange[a]) if model.actuator_forcelimited[a] else None
    trn = int(model.actuator_trntype[a])
    target = int(model.actuator_trnid[a][0])
    base = {
        "name": name,
        "kind": _kind(model, a),
        "joint": None,
        "tendon": None,
        "articulation": None,
        "dofs": (),
        "gear": gear,
        "ctrlrange": ctrlrange,
        "forcerange": forcerange,
    }
    if disabled:
        return ActuatorMap(**base, mapped=False, reason="actuation disabled by the model's <flag actuation>"), None
    dyntype = int(model.actuator_dyntype[a])
    unmapped = _unmapped_law(model, a, dyntype)
    if unmapped:
        return ActuatorMap(**base, mapped=False, reason=unmapped), None
    if _is_muscle(model, a):
        base.update(dynamics=MAPPED_DYNAMICS.get(dyntype, "none"), muscle=True)
        return _moment_actuator(model, mapping, a, base, np.zeros(3))
    bias = model.actuator_biasprm[a] if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_AFFINE) else np.zeros(3)
    base["gain"] = float(model.actuator_gainprm[a][0])
    base["dynamics"] = MAPPED_DYNAMICS.get(dyntype, "none")
    base["bias"] = (float(bias[0]), float(bias[1]), float(bias[2]))
    jointed = trn in (int(TRN.mjTRN_JOINT), int(TRN.mjTRN_JOINTINPARENT))
    if trn in MOMENT_TRANSMISSIONS or (jointed and mapping.joints[target].kind == "free"):
        return _moment_actuator(model, mapping, a, base, bias)
    if jointed:  # on a hinge or slide, jointinparent is joint
        joint = mapping.joints[target]
        if joint.kind not in DRIVEN:
            return ActuatorMap(**base, mapped=False, reason=f"drives a {joint.kind} joint"), None
        stiffness, damping = -bias[1] * gear**2, -bias[2] * gear**2
        base.update(joint=mj.name(model, "joint", target), articulation=joint.articulation, dofs=joint.dofs)
        return ActuatorMap(**base, stiffness=float(stiffness), damping=float(damping)), None
    if trn == int(TRN.mjTRN_TENDON):
        terms = mj.fixed_tendon_terms(model, target)
        if not terms:  # a spatial tendon: its path and Jacobian are MuJoCo's at every step (`runtime/tendon_paths.py`)
            if not mapping.carries(model, target):
                return ActuatorMap(**base, mapped=False, reason="its spatial tendon crosses a ball joint"), None
            joints = [mapping.joints[int(model.dof_jntid[d])] for d in sorted(mj.tendon_dofs(model, target))]
            hinges = [j for j in joints if j.kind in DRIVEN]
            base.update(
                tendon=mj.name(model, "tendon", target),
                dofs=tuple(j.dofs[0] for j in hinges),
                articulation=hinges[0].articulation if hinges else None,
            )
            return ActuatorMap(**base, stiffness=float(-bias[1] * gear**2), damping=float(-bias[2] * gear**2)), SPATIAL
        mapped_terms = []
        for joint_id, coefficient in terms:
            joint = mapping.joints[joint_id]
            if joint.kind not in DRIVEN:
                return ActuatorMap(**base, mapped=False, reason="its tendon crosses a ball or free joint"), None
            mapped_terms.append((joint.articulation, joint.dofs[0], coefficient))
        base.update(
            tendon=mj.name(model, "tendon", target),
            articulation=mapped_terms[0][0],
            dofs=tuple(d for _, d, _ in mapped_terms),
        )
        return ActuatorMap(**base, stiffness=float(-bias[1] * gear**2), damping=float(-bias[2] * gear**2)), mapped_terms
    kind = TRN(trn).name.removeprefix("mjTRN_").lower()
    return ActuatorMap(**base, mapped=False, reason=f"{kind} transmission is not mapped"), None


MOMENT_TRANSMISSIONS = (int(TRN.mjTRN_SITE), int(TRN.mjTRN_SLIDERCRANK), int(TRN.mjTRN_BODY))


def _unmapped_law(model: mujoco.MjModel, a: int, dyntype: int) -> str:
    """Why the actuator's force law is not mapped ('' where it is): user dynamics, gains or biases."""
    if dyntype != int(DYN.mjDYN_NONE) and dyntype not in MAPPED_DYNAMICS:
        return f"activation dynamics ({DYN(dyntype).name.removeprefix('mjDYN_').lower()}) are not mapped"
    affine = int(model.actuator_gaintype[a]) == int(GAIN.mjGAIN_FIXED) and int(model.actuator_biastype[a]) in (
        int(BIAS.mjBIAS_NONE),
        int(BIAS.mjBIAS_AFFINE),
    )
    return "" if affine or _is_muscle(model, a) else "gain or bias is not affine or a muscle's (user)"


def _is_muscle(model: mujoco.MjModel, a: int) -> bool:
    """MuJoCo's muscle: its gain and bias are the muscle curves (`<muscle>` sets both; a bias may be absent)."""
    return int(model.actuator_gaintype[a]) == int(GAIN.mjGAIN_MUSCLE) and int(model.actuator_biastype[a]) in (
        int(BIAS.mjBIAS_MUSCLE),
        int(BIAS.mjBIAS_NONE),
    )


def _moment_actuator(model: mujoco.MjModel, mapping: Mapping, a: int, base: dict, bias) -> tuple[ActuatorMap, list]:
    """An actuator whose length and moment MuJoCo's transmission computes (a site, with or without a reference
    site; a slider-crank; a body, from its contacts; a joint or jointinparent transmission on a free joint; a
    muscle on any transmission):
    mapped where SAPIEN carries a force on every DoF it can move (hinges, slides, a free joint's root), with gear 1,
    as MuJoCo's moment holds the gear (a body's takes none)."""
    dofs = sorted(mj.transmission_dofs(model, a))
    joints = [mapping.joints[int(model.dof_jntid[d])] for d in dofs]
    if any(j.kind not in CARRIED for j in joints):
        return ActuatorMap(**base, mapped=False, reason="its transmission moves a ball joint"), None
    hinges = [j for j in joints if j.kind in DRIVEN]
    base.update(
        gear=1.0,
        dofs=tuple(j.dofs[0] for j in hinges),
        articulation=joints[0].articulation if joints else None,
        moment=True,
    )
    return ActuatorMap(**base, stiffness=float(-bias[1]), damping=float(-bias[2])), MOMENT


def map_actuators(model: mujoco.MjModel, mapping: Mapping, notes) -> list[tuple[ActuatorMap, list | None]]:
    """Every actuator's map with its tendon's terms (`map_actuator`); an unmapped one is noted with its reason."""
    disabled = mj.disabled(model, "actuation")
    maps = [map_actuator(model, mapping, a, disabled) for a in range(model.nu)]
    for entry, _ in maps:
        if not entry.mapped:
            notes.drop("actuator", entry.name, entry.reason)
    return maps
