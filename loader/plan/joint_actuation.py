"""MuJoCo's joint actuators and joint springs and dampers as flat arrays, planned once from the compiled model, for a
law over (env, DoF) that needs no MuJoCo call each step (`loader/maniskill/joint_actuation.py`, which runs it on
ManiSkill's state tensors, on the CPU or the GPU).

Per actuator on a hinge, a slide or a fixed tendon over them (MuJoCo's constant moment m = dL/dq: the gear, times
the tendon's coefficients), with a fixed gain and a bias that is none or affine, MuJoCo's force at the state is

    F = clamp(gain u + b0 + b1 L + b2 dL/dt, forcerange),   L = m q,   joint forces m F,

with u the clamped ctrl, or the activation where the actuator has one (an integrator or a filter: the per-step half
steps it as MuJoCo does); the sum of a joint's actuator forces clamped to its actuatorfrcrange; and each DoF adds
its spring k (springref - q) and damper -d v; a body compensated fully (gravcomp 1) weighs nothing. MuJoCo's
integrator takes the dampers, and under the implicit integrators each actuator's -b2 m m^T (its kv on the joints),
implicitly: the dampers and that term's diagonal stay in a PhysX drive (damping, no stiffness), whose implicit law
matches MuJoCo's step under PGS whatever velocity it aims at; a fixed tendon's cross terms are explicit. The joint
force the law writes is everything else, evaluated at the step's start: m F, with each held kv's start term moved
into its place and the drive's pull at its aim taken back. Where forcerange or actuatorfrcrange binds, the force is
constant in MuJoCo and the drive's share pulls by how far the end velocity misses its aim (the per-step half aims at
an estimate of it): with the tendon's explicit cross terms, the law's only approximations. With the drives aimed
at the state's velocity, the law's force is MuJoCo's qfrc_actuator + qfrc_passive at any state; PhysX's gravity off
on a fully compensated body's link is MuJoCo's gravity and compensation together
(tests/test_maniskill_joint_actuation.py::test_the_law_and_its_drives_give_mujocos_actuator_and_passive_force;
tests/test_joint_actuation.py::test_the_drives_hold_mujocos_velocity_derivative_under_implicitfast;
tests/test_maniskill_joint_actuation.py::test_a_compensated_arm_follows_mujoco_with_its_links_weightless).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..model import mj
from ..model.joints import dof_damping, joint_stiffness
from ..model.mapping import Mapping

TRANSMISSIONS = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_TENDON))
JOINT_WRAP = int(mujoco.mjtWrap.mjWRAP_JOINT)
SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
NO_DYNAMICS = int(mujoco.mjtDyn.mjDYN_NONE)
INTEGRATOR, FILTER, FILTEREXACT = (
    int(mujoco.mjtDyn.mjDYN_INTEGRATOR),
    int(mujoco.mjtDyn.mjDYN_FILTER),
    int(mujoco.mjtDyn.mjDYN_FILTEREXACT),
)
DYNAMICS = (NO_DYNAMICS, INTEGRATOR, FILTER, FILTEREXACT)  # the activations the law steps itself
FIXED_GAIN = int(mujoco.mjtGain.mjGAIN_FIXED)
BIASES = (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE))
EXPLICIT_ACTUATORS = mj.EULER_LIKE  # an actuator's kv is explicit there (RK4: simulated as Euler)


@dataclass
class JointActuation:
    """The law's arrays: per actuator, its moment over the robot's active DoFs (`ndof` of them), per DoF, and what
    the law leaves out (`not_carried`)."""

    ndof: int
    moment: np.ndarray  # (nu, ndof): dL/dq, MuJoCo's (gear, times a fixed tendon's coefficients), constant here
    gain: np.ndarray
    bias: np.ndarray  # (3, nu): b0, b1, b2
    held: np.ndarray  # 1.0 where the drives hold the actuator's velocity term (its diagonal), else 0.0
    ctrl_range: np.ndarray  # (2, nu): -inf, inf where ctrl is not clamped
    force_range: np.ndarray  # (2, nu): -inf, inf where the force is not clamped
    joint_range: np.ndarray  # (2, ndof): each DoF's actuatorfrcrange, -inf, inf where it has none
    dynamics: np.ndarray  # per actuator: MuJoCo's dyntype (none, integrator, filter, filterexact)
    time_constant: np.ndarray  # per actuator: a filter's dynprm[0] (at least mjMINVAL), else 1
    act_range: np.ndarray  # (2, nu): actrange where actlimited, else -inf, inf
    act_early: np.ndarray  # per actuator: the force reads the step's next activation (actearly)
    stiffness: np.ndarray  # per DoF
    spring_ref: np.ndarray
    drive_damping: np.ndarray  # per DoF: the damping its PhysX drive holds
    explicit_damping: np.ndarray  # per DoF: damping the law applies at the start state (eulerdamp disabled)
    # the robot links of the bodies compensated fully (gravcomp 1): PhysX's gravity off on them is MuJoCo's gravity
    # and its compensation at their centres of mass together
    weightless: list[int] = field(default_factory=list)
    not_carried: list[str] = field(default_factory=list)

    def held_damping(self) -> np.ndarray:
        return held_damping(self.held, self.bias, self.moment)


def held_damping(held: np.ndarray, bias: np.ndarray, moment: np.ndarray) -> np.ndarray:
    """Per DoF, the actuators' velocity terms the drives hold: sum over held actuators of -b2 m^2."""
    return (held * -bias[2]) @ moment**2


def plan_joint_actuation(
    model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int, link_of_body: dict[int, int] | None = None
) -> JointActuation | str:
    """The law for `model` whose MuJoCo joint j moves robot DoF `dof_of_joint[j]` (hinges and slides) and whose body
    b is robot link `link_of_body[b]`, or why the law cannot drive it (an actuator outside its scope)."""
    why = _outside(model, dof_of_joint)
    if why is not None:
        return why
    actuated = not mj.disabled(model, "actuation")
    affine = (model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)).astype(float)
    bias = (model.actuator_biasprm[:, :3] * affine[:, None]).T.copy() if model.nu else np.zeros((3, 0))
    gain = model.actuator_gainprm[:, 0].copy()
    off = ((int(model.opt.disableactuator) >> np.clip(model.actuator_group, 0, 30)) & 1).astype(bool) | (not actuated)
    gain[off], bias[:, off] = 0.0, 0.0  # actuation disabled, or the actuator's group (`disableactuator`)
    implicit = int(model.opt.integrator) not in EXPLICIT_ACTUATORS
    held = ((bias[2] < 0) & implicit).astype(float)  # PhysX's damping cannot be negative
    clamps = model.actuator_ctrllimited.astype(bool) & (not mj.disabled(model, "clampctrl"))
    ctrl_range = np.where(clamps, model.actuator_ctrlrange.T, [[-np.inf], [np.inf]])
    force_range = np.where(model.actuator_forcelimited.astype(bool), model.actuator_forcerange.T, [[-np.inf], [np.inf]])
    stiffness, spring_ref, damping, joint_range = _joint_arrays(model, dof_of_joint, ndof)
    damped_explicitly = mj.explicit_damping(model)
    moment = _moment(model, dof_of_joint, ndof)
    held_terms = held_damping(held, bias, moment)
    dynamics = model.actuator_dyntype.astype(np.int64)
    filtered = (dynamics == FILTER) | (dynamics == FILTEREXACT)
    time_constant = np.where(filtered, np.maximum(model.actuator_dynprm[:, 0], mj.MJMINVAL), 1.0)
    act_range = np.where(model.actuator_actlimited.astype(bool), model.actuator_actrange.T, [[-np.inf], [np.inf]])
    return JointActuation(
        ndof,
        moment,
        gain,
        bias,
        held,
        ctrl_range,
        force_range,
        joint_range,
        dynamics,
        time_constant,
        act_range,
        model.actuator_actearly.astype(bool),
        stiffness,
        spring_ref,
        held_terms + (0.0 if damped_explicitly else damping),
        damping if damped_explicitly else np.zeros(ndof),
        _weightless(model, link_of_body or {}),
        _not_carried(model, link_of_body or {}, _crossed(held, moment)),
    )


def robot_indices(mapping: Mapping, articulation: int = 0) -> tuple[dict[int, int], dict[int, int]]:
    """For one articulation (a ManiSkill robot): MuJoCo joint -> its SAPIEN DoF for each hinge and slide, and MuJoCo
    body -> its link, as `plan_joint_actuation` takes them."""
    dofs = {
        j: target.dofs[0]
        for j, target in enumerate(mapping.joints)
        if target.drive_key is not None and target.articulation == articulation
    }
    links = {b: t.link for b, t in enumerate(mapping.bodies) if t is not None and t.articulation == articulation}
    return dofs, links


def _moment(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> np.ndarray:
    """MuJoCo's actuator moments (nu, ndof) in the robot's DoF order, from its transmission pass at qpos0: constant
    for a hinge or slide and for a fixed tendon over them."""
    data = mujoco.MjData(model)
    mujoco.mj_fwdPosition(model, data)
    dense = np.zeros((model.nu, model.nv))
    if model.nu:
        mujoco.mju_sparse2dense(dense, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind)
    moment = np.zeros((model.nu, ndof))
    for joint, robot_dof in dof_of_joint.items():
        moment[:, robot_dof] = dense[:, model.jnt_dofadr[joint]]
    return moment


def _joint_arrays(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> tuple[np.ndarray, ...]:
    """Per robot DoF: the spring's stiffness and reference, the damper, the actuatorfrcrange (-inf, inf: none)."""
    stiffness, spring_ref, damping = np.zeros(ndof), np.zeros(ndof), np.zeros(ndof)
    joint_range = np.tile([[-np.inf], [np.inf]], (1, ndof))
    for joint, robot_dof in dof_of_joint.items():
        if model.jnt_actfrclimited[joint]:
            joint_range[:, robot_dof] = model.jnt_actfrcrange[joint]
        stiffness[robot_dof] = joint_stiffness(model, joint)
        spring_ref[robot_dof] = model.qpos_spring[model.jnt_qposadr[joint]]
        damping[robot_dof] = dof_damping(model, int(model.jnt_dofadr[joint]))
    return stiffness, spring_ref, damping, joint_range


def _weightless(model: mujoco.MjModel, link_of_body: dict[int, int]) -> list[int]:
    """The links of the fully compensated bodies, where the compensation is a passive force (not routed through the
    actuators, `actuatorgravcomp`) and gravity is on."""
    if np.any(model.jnt_actgravcomp) or mj.disabled(model, "gravity"):
        return []
    return sorted(link for body, link in link_of_body.items() if model.body_gravcomp[body] == 1.0)


def _outside(model: mujoco.MjModel, dof_of_joint: dict[int, int]) -> str | None:
    """Why an actuator is outside the law's scope, naming it; None where every one is inside."""
    for a in range(model.nu):
        name = mj.name(model, "actuator", a)
        if int(model.actuator_trntype[a]) not in TRANSMISSIONS:
            return f"actuator {name!r} drives a site, body or slider-crank, not a joint or tendon"
        joints = _transmission_joints(model, a)
        if joints is None:
            return f"actuator {name!r} drives a spatial tendon (its moment changes with the pose)"
        for joint in joints:
            if int(model.jnt_type[joint]) not in SCALAR_JOINTS:
                return f"actuator {name!r} drives a ball or free joint"
            if joint not in dof_of_joint:
                where = mj.name(model, "joint", joint)
                return f"actuator {name!r} drives joint {where!r}, outside the robot's articulation"
        if int(model.actuator_dyntype[a]) not in DYNAMICS:
            return f"actuator {name!r} has activation dynamics other than an integrator or a filter"
        if int(model.actuator_gaintype[a]) != FIXED_GAIN or int(model.actuator_biastype[a]) not in BIASES:
            return f"actuator {name!r} has a gain or bias that is not fixed or affine"
    return None


def _transmission_joints(model: mujoco.MjModel, actuator: int) -> list[int] | None:
    """The joints an actuator's joint or fixed tendon moves; None for a spatial tendon."""
    target = int(model.actuator_trnid[actuator, 0])
    if int(model.actuator_trntype[actuator]) == TRANSMISSIONS[0]:
        return [target]
    start, count = int(model.tendon_adr[target]), int(model.tendon_num[target])
    wraps = range(start, start + count)
    if any(int(model.wrap_type[w]) != JOINT_WRAP for w in wraps):
        return None
    return [int(model.wrap_objid[w]) for w in wraps]


def _crossed(held: np.ndarray, moment: np.ndarray) -> bool:
    """Whether an actuator whose velocity term the drives hold moves several DoFs (a fixed tendon over joints): its
    -b2 m m^T couples them, and the drives hold only the diagonal."""
    return bool(np.any((held > 0) & (np.count_nonzero(moment, axis=1) > 1)))


def _not_carried(model: mujoco.MjModel, link_of_body: dict[int, int], crossed: bool) -> list[str]:
    """What MuJoCo's model holds beyond the law and the build: each is PhysX's own or absent on this path (`crossed`:
    a held velocity term's cross terms, `_crossed`)."""
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    floating = any(
        int(model.jnt_type[j]) == free and int(model.jnt_bodyid[j]) in link_of_body for j in range(model.njnt)
    )
    checks = [
        (floating, "a floating root's velocity in MuJoCo's convention (PhysX's step conserves momentum)"),
        (
            np.any(model.jnt_limited) and not mj.disabled(model, "limit", "constraint"),
            "soft joint limits (PhysX's hard limits)",
        ),
        (np.any(model.dof_frictionloss > 0) and not mj.disabled(model, "frictionloss", "constraint"), "frictionloss"),
        (
            np.any(model.tendon_stiffness)
            or np.any(model.tendon_damping)
            or (np.any(model.tendon_limited) and not mj.disabled(model, "limit", "constraint")),
            "tendon springs, dampers and limits",
        ),
        (np.any(model.tendon_frictionloss > 0), "tendon frictionloss"),
        (model.neq > 0 and not mj.disabled(model, "equality", "constraint"), "equality constraints"),
        (np.any((model.body_gravcomp != 0) & (model.body_gravcomp != 1)), "partial gravity compensation"),
        (np.any(model.jnt_actgravcomp) and np.any(model.body_gravcomp), "gravity compensation through the actuators"),
        (model.opt.density > 0 or model.opt.viscosity > 0, "fluid forces"),
        (int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_IMPLICIT), "the implicit integrator's Coriolis"),
        (np.any(model.actuator_biasprm[:, 2] > 0), "an actuator's positive velocity gain (explicit here)"),
        (crossed, "the velocity cross terms of an actuator on a fixed tendon (explicit here)"),
    ]
    return [what for present, what in checks if present]
