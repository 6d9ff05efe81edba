"""Open loader bugs, each reproduced by a file in `corpus/regressions/` (reason in `known_bugs.toml`).

While a bug is open, a generated document that can trigger it would fail the properties for a reason already
on record. Each entry says which documents can trigger it and which tiers it breaks; such a tier failure is
counted as "known bug <file>" (never silently passed). Delete the entry when the loader is fixed: the
regression's strict xfail turns into an XPASS error that day, as a reminder.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from ..reference import limited_dofs


@dataclass(frozen=True)
class KnownBug:
    regression: str  # file name in corpus/regressions/
    tiers: tuple[str, ...]
    triggers: Callable[[object, mujoco.MjModel], bool]  # (load result, compiled model)
    diverges: bool = False  # its finds include a SAPIEN run past the speed bound, excused like a failure
    terms_only: bool = False  # the per-step terms' bug (`law = "terms"`): no excuse where MuJoCo's own step runs


ILL_CONDITIONED = 50.0  # condition number of MuJoCo's joint-space inertia at qpos0 beyond which one-step
# accelerations were seen 0.1-0.3 % off (fuzz finds at 128, 335 and 363; 70 agreed to 2e-6)


def _joint_space_inertia(model: mujoco.MjModel) -> np.ndarray:
    """MuJoCo's joint-space inertia at qpos0 (nv x nv)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return full


def _ill_conditioned(result, model: mujoco.MjModel) -> bool:
    if model.nv < 2:
        return False
    return bool(np.linalg.cond(_joint_space_inertia(model)) > ILL_CONDITIONED)


SLENDER = 50.0  # a hinge whose body turns with less than 1/SLENDER of its largest principal moment about the axis


def _slender_about_a_hinge(result, model: mujoco.MjModel) -> bool:
    """A hinge whose joint-space inertia at qpos0 is under 1/SLENDER of its body's largest principal moment: PhysX's
    float32 world-frame inertia then loses the small moment about the axis."""
    hinges = [j for j in range(model.njnt) if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)]
    if not hinges:
        return False
    full = _joint_space_inertia(model)
    for j in hinges:
        largest = float(model.body_inertia[int(model.jnt_bodyid[j])].max())
        dof = int(model.jnt_dofadr[j])
        if full[dof, dof] * SLENDER < largest:
            return True
    return False


LIGHT_LINK = 1e-6  # kg: a jointed body this light, started past a limit


def _started_past_their_ends(model: mujoco.MjModel) -> list[int]:
    """The limited hinges and slides (`reference.limited_dofs`) that the first keyframe starts outside their range."""
    if not model.nkey:
        return []
    start = model.key_qpos[0]
    return [j for j, adr, lo, hi in limited_dofs(model) if not lo <= start[adr] <= hi]


def _light_link_started_past_its_end(result, model: mujoco.MjModel) -> bool:
    """A jointed body under LIGHT_LINK kg with a limited joint that the first keyframe starts past its range."""
    return any(model.body_mass[int(model.jnt_bodyid[j])] < LIGHT_LINK for j in _started_past_their_ends(model))


UNCONVERGED = 1  # MuJoCo's solver iterations at or below which a start past a limit was seen off (finds at 1 pass at 2)


def _unconverged_started_past_its_end(result, model: mujoco.MjModel) -> bool:
    """MuJoCo's solve stopped after UNCONVERGED iterations or fewer (MuJoCo Playground's setting) with a limited joint
    that the first keyframe starts past its range: the limit rows act from the first step, unconverged."""
    return int(model.opt.iterations) <= UNCONVERGED and bool(_started_past_their_ends(model))


FAST = 100.0  # rad/s or m/s: a one-step speed change a position servo can make on its DoF, beyond which float32
# was seen off (robot_classes-1fb34010df.xml: 240; 24 agreed)


def _servo_spins_fast(result, model: mujoco.MjModel) -> bool:
    """A position-like servo (gain kp, bias -kp q) that can change its DoF's speed by more than FAST in one step:
    dt kp (ctrlrange span) / M_ii, with MuJoCo's joint-space inertia at qpos0."""
    diagonal = np.diag(_joint_space_inertia(model))
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT) or not model.actuator_ctrllimited[a]:
            continue
        kp = float(model.actuator_gainprm[a, 0])
        dof = int(model.jnt_dofadr[int(model.actuator_trnid[a, 0])])
        span = float(np.ptp(model.actuator_ctrlrange[a]))
        if kp > 0 and model.opt.timestep * kp * span * abs(model.actuator_gear[a, 0]) > FAST * diagonal[dof]:
            return True
    return False


SLIDE_FAR = 1.0  # m: a slide's qpos0 (its ref) this far from zero, where the loader moves its joint frame along the
# axis (finds failed at 2, 20 and 28 m and passed at 1 and 14 m)


def _slide_far_from_its_zero(result, model: mujoco.MjModel) -> bool:
    """A slide whose reference position is SLIDE_FAR or more from zero: PhysX's joint coordinate is MuJoCo's qpos,
    so the loader moves the joint frame that far along the axis, and float32 across that offset scales with it."""
    slides = [j for j in range(model.njnt) if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE)]
    return any(abs(float(model.qpos0[int(model.jnt_qposadr[j])])) >= SLIDE_FAR for j in slides)


# fixed in the loader: free_joint_class_damping_armature.xml (now listed as unsupported),
# zero_dof_tree_child_pose.xml (set_state updates joint-less trees) and velocity_actuator_unreached_forcerange.xml
# (the drive force limit is listed as an approximation), slide_*_metres_from_its_zero.xml (joint frames onto a
# coordinate axis are exact in float32 now, `loader/frames.py`), slide_far_from_its_zero_off_axis.xml (the one-step
# tiers start MuJoCo from the float32 state SAPIEN holds), robot_classes-e5bbc90029.xml (a joint-space inertia
# conditioned beyond float32 is listed by the loader, `plan/features.py`), conformance-fe7078d2ce.xml (a free body's
# root velocity comes from MuJoCo's rows, not PhysX's float32 momentum across the slide's lever,
# `runtime/momentum.py`); their files stay as regressions
KNOWN_BUGS: list[KnownBug] = [
    KnownBug("ill_conditioned_two_hinges.xml", ("dynamics", "actuated"), _ill_conditioned),
    KnownBug("slender_rod_about_its_axis.xml", ("dynamics", "actuated"), _slender_about_a_hinge),
    KnownBug("robot_classes-1fb34010df.xml", ("actuated",), _servo_spins_fast),
    KnownBug(
        "robot_classes-290ddd7193.xml",
        ("dynamics", "actuated"),
        _light_link_started_past_its_end,
        diverges=True,
        terms_only=True,
    ),
    KnownBug("robot_classes-8d38111bd9.xml", ("dynamics", "actuated"), _unconverged_started_past_its_end),
    KnownBug("conformance-c24daadc9b.xml", ("dynamics", "actuated"), _slide_far_from_its_zero),
]


def known_bug(tier: str, result, model: mujoco.MjModel, diverged: bool = False) -> str | None:
    """The regression file of an open bug that explains a failure of `tier` on this model, if any; a divergence
    (`diverged`) only by a bug whose finds diverge."""
    for bug in KNOWN_BUGS:
        if tier not in bug.tiers or (diverged and not bug.diverges):
            continue
        if bug.terms_only and result is not None and result.controller.law() == "mujoco_step":
            continue
        if bug.triggers(result, model):
            return bug.regression
    return None
