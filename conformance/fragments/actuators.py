"""Actuators against what MuJoCo compiled: gear, control and force ranges, the joint, and the drive gains.

For a joint actuator with gear g, MuJoCo's force is g*(gain*ctrl + b0 + b1*g*q + b2*g*qdot), so its joint-space
stiffness is -b1*g^2 and its damping -b2*g^2 (kp*g^2 and kv*g^2 for `<position>`); `result.actuators` holds
those terms. The PhysX drive of a hinge/slide DoF sums them with the joint's own spring and damping, and since
MuJoCo (implicitfast) integrates stiffness explicitly but PhysX implicitly, its damping is the sum minus
stiffness*timestep (clamped at 0, which the loader lists as an approximation). Class-resolved values
(kp/kv/gear/ctrlrange from a default class, shortcut resets) are read here only from the compiled model.
"""

from __future__ import annotations

import mujoco
import numpy as np

_REL = 1e-9  # loader values are float64 copies of MuJoCo's; only arithmetic rounding separates them
_JT = mujoco.mjtJoint


def expected_gains(model: mujoco.MjModel, a: int) -> tuple[float, float]:
    """(stiffness, damping) in joint space that the loader should hold for actuator `a` (joint transmission)."""
    gear = float(model.actuator_gear[a][0])
    if int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE):
        bias = model.actuator_biasprm[a]
    else:
        bias = np.zeros(3)
    return -float(bias[1]) * gear**2, -float(bias[2]) * gear**2


_DYNAMICS = tuple(
    int(d)
    for d in (
        mujoco.mjtDyn.mjDYN_NONE,
        mujoco.mjtDyn.mjDYN_FILTER,
        mujoco.mjtDyn.mjDYN_FILTEREXACT,
        mujoco.mjtDyn.mjDYN_INTEGRATOR,
    )
)


def _mappable(model: mujoco.MjModel, a: int) -> bool:
    """A joint actuator on a hinge/slide with a fixed gain and no activation dynamics, or filter / integrator
    dynamics (MuJoCo's activation replaces ctrl in the gain): exact as a drive."""
    if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
        return False
    joint = int(model.actuator_trnid[a][0])
    return (
        int(model.jnt_type[joint]) in (int(_JT.mjJNT_HINGE), int(_JT.mjJNT_SLIDE))
        and int(model.actuator_dyntype[a]) in _DYNAMICS
        and int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
        and int(model.actuator_biastype[a]) in (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE))
    )


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= _REL * max(1.0, abs(a), abs(b))


def _range(model_limited, model_range) -> tuple[float, float] | None:
    return (float(model_range[0]), float(model_range[1])) if model_limited else None


def _not_a_drive(entry, name: str) -> tuple[bool, str]:
    """(a mismatch?, what to say) of an actuator MuJoCo does not make a hinge/slide drive: one whose moment changes
    with the pose is the dynamic tiers' to judge; another must be unmapped."""
    if entry.moment:
        return (
            False,
            "actuators: a moment MuJoCo computes (site, slider-crank, body, free joint, muscle): judged by rollouts",
        )
    if entry.mapped:
        return True, f"actuator {name!r}: mapped although MuJoCo's actuator is not a joint drive"
    return False, f"actuators: not a hinge/slide drive ({entry.reason.split(':')[0]})"


def actuator_mismatches(result, model: mujoco.MjModel) -> tuple[list[str], list[str], int]:
    """(mismatches, skipped, checked) of `result.actuators` against the compiled actuators."""
    actuators = result.actuators
    if model.nu == 0:
        return [], [], 0
    if len(actuators) != model.nu:
        return [f"{len(actuators)} actuator entries for {model.nu} MuJoCo actuators"], [], 0
    out, skipped, checked = [], [], 0
    for a, entry in enumerate(actuators):
        name = model.actuator(a).name or f"actuator{a}"
        if not _mappable(model, a):
            wrong, why = _not_a_drive(entry, name)
            (out if wrong else skipped).append(why)
            continue
        if not entry.mapped:
            out.append(f"actuator {name!r}: not mapped ({entry.reason}) although it is a hinge/slide drive")
            continue
        checked += 1
        joint = int(model.actuator_trnid[a][0])
        target = result.mapping.joints[joint]
        if (entry.articulation, tuple(entry.dofs)) != (target.articulation, tuple(target.dofs)):
            out.append(
                f"actuator {name!r}: drives articulation {entry.articulation} dofs {entry.dofs}, joint "
                f"{joint} is articulation {target.articulation} dofs {target.dofs}"
            )
        if not _close(entry.gear, float(model.actuator_gear[a][0])):
            out.append(f"actuator {name!r}: gear {entry.gear}, MuJoCo {model.actuator_gear[a][0]}")
        for field, want in (
            ("ctrlrange", _range(model.actuator_ctrllimited[a], model.actuator_ctrlrange[a])),
            ("forcerange", _range(model.actuator_forcelimited[a], model.actuator_forcerange[a])),
        ):
            got = getattr(entry, field)
            if (got is None) != (want is None) or (got is not None and not all(map(_close, got, want))):
                out.append(f"actuator {name!r}: {field} {got}, MuJoCo {want}")
        stiffness, damping = expected_gains(model, a)
        if not (_close(entry.stiffness, stiffness) and _close(entry.damping, damping)):
            out.append(
                f"actuator {name!r}: drive stiffness {entry.stiffness:.9g} damping {entry.damping:.9g}, "
                f"MuJoCo compiled stiffness {stiffness:.9g} damping {damping:.9g} "
                f"(kp={model.actuator_gainprm[a][0]:g}, "
                f"bias={list(model.actuator_biasprm[a][:3])}, gear={model.actuator_gear[a][0]:g})"
            )
    return out, skipped, checked


def drive_mismatches(result, model: mujoco.MjModel) -> tuple[list[str], int]:
    """Per hinge/slide DoF, the PhysX drive (actuators enabled, ctrl 0) against MuJoCo's compiled terms.

    Read at q = 0, qdot = 0, where no actuator force can sit on a forcerange or actuatorfrcrange bound (there the
    loader applies the clamped force explicitly and the drive keeps the passive terms only). MuJoCo's rules: kv is
    implicit under implicit/implicitfast and explicit under Euler and RK4, damping implicit, kp and springs
    explicit; a drive is implicit in what it holds, so a DoF whose implicit damping cannot absorb its stiffness
    (kp, spring) times dt keeps the stiffness out of its drive (explicit force), and a frictional DoF's drive holds
    only its friction row. Those are the per-step terms' drives: where MuJoCo's own step gives the joint forces (the
    loader's default where the model allows), its drives hold the implicit damping alone and the tiers judge its
    law, so the terms run for this check and the loader's law runs again after it."""
    with result.controller.on_terms():
        return _terms_drive_mismatches(result, model)


def _terms_drive_mismatches(result, model: mujoco.MjModel) -> tuple[list[str], int]:
    for art in result.articulations:
        art.set_qpos(np.zeros(art.dof, np.float32))
        art.set_qvel(np.zeros(art.dof, np.float32))
    result.set_ctrl(np.zeros(model.nu))
    stiffness = {}
    damping = {}
    for j, target in enumerate(result.mapping.joints):
        if target.kind in ("hinge", "slide"):
            key = (target.articulation, target.dofs[0])
            stiffness[key] = float(model.jnt_stiffness[j])
            damping[key] = float(model.dof_damping[model.jnt_dofadr[j]])
    enabled = not (model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION))
    implicit_kv = int(model.opt.integrator) in (
        int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
        int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
    )
    for a in range(model.nu):
        if enabled and _mappable(model, a):
            target = result.mapping.joints[int(model.actuator_trnid[a][0])]
            key = (target.articulation, target.dofs[0])
            k, d = expected_gains(model, a)
            stiffness[key] += k
            damping[key] += d if implicit_kv else 0.0
    out = []
    dt = float(model.opt.timestep)
    for key, want_k in stiffness.items():
        joint = result.articulations[key[0]].active_joints[key[1]]
        want_d = max(damping[key] - want_k * dt, 0.0)
        if damping[key] - want_k * dt < 0:  # the stiffness (kp, spring) explicit
            want_k, want_d = 0.0, damping[key]
        got_k, got_d = float(joint.stiffness), float(joint.damping)
        if not (_close32(got_k, want_k) and _close32(got_d, want_d)):
            out.append(
                f"joint {joint.name!r}: PhysX drive stiffness {got_k:.7g} damping {got_d:.7g}, MuJoCo's "
                f"terms give stiffness {want_k:.7g} damping {want_d:.7g} (dt {dt:g})"
            )
    return out, len(stiffness)


def _close32(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-6 * max(1.0, abs(a), abs(b))  # PhysX stores float32


def check_actuators(result, outcome) -> tuple[int, int]:
    """Add actuator and drive mismatches and skips to a properties `Outcome` (call before the actuators are
    disabled for the tiers); returns (actuators checked, DoFs whose drive gains were checked)."""
    mismatches, skipped, checked = actuator_mismatches(result, result.model)
    drives, dofs = drive_mismatches(result, result.model)
    outcome.failures += mismatches + drives
    outcome.skipped += skipped
    return checked, dofs
