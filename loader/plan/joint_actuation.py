"""MuJoCo's joint actuators and joint springs and dampers as flat arrays, planned once from the compiled model, for a
law over (env, DoF) that needs no MuJoCo call each step (`loader/maniskill/joint_actuation.py`, which runs it on
ManiSkill's state tensors, on the CPU or the GPU).

Per actuator on a hinge, a slide or a fixed tendon over them (MuJoCo's constant moment m = dL/dq: the gear, times
the tendon's coefficients), with a fixed gain and a bias that is none or affine, MuJoCo's force at the state is

    F = clamp(gain u + b0 + b1 L + b2 dL/dt, forcerange),   L = m q,   joint forces m F,

with u the clamped ctrl, or the activation where the actuator has one (an integrator or a filter: the per-step half
steps it as MuJoCo does); the sum of a joint's actuator forces clamped to its actuatorfrcrange; and each DoF adds
its spring k (springref - q) and damper -d v, and each fixed tendon over the robot's joints its linear spring (zero
between its two rest lengths) and damper through its coefficients; a body compensated fully (gravcomp 1) weighs
nothing. MuJoCo's step takes the joints' dampers implicitly (unless eulerdamp is off), and under the implicit
integrators each actuator's -b2 m m^T (but where its forcerange binds) and each tendon's damper d m m^T too, only
between DoFs on one chain of the tree (a cross term between two branches, a gripper's fingers, is dropped: the mass
matrix's pattern). Each limited hinge and slide adds MuJoCo's soft limit rows (`JointLimits`: solref, solimp,
margin), each with frictionloss its row (`JointFriction`), each fixed tendon over them the same on its length
(`TendonRows`), each coupling of joints or fixed tendons its equality row (`JointCouplings`). The per-step half
solves that step with the robot's M and c
(tests/test_maniskill_joint_actuation.py::test_the_law_gives_mujocos_actuator_and_passive_force,
tests/test_joint_actuation.py::test_the_planned_implicit_derivative_is_mujocos_step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..model import mj
from ..model.joints import dof_damping, is_limited, joint_stiffness
from ..model.mapping import Mapping
from ..model.soft_row import SoftRow, diag_approx
from .spatial_tendon import SpatialTendons, plan_spatial_tendons, why_outside

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
class TendonSprings:
    """The fixed tendons over the robot's joints with a (linear) spring or damper: per tendon its moment over the
    DoFs (its coefficients), its stiffness, its spring's rest lengths (a deadband between them), its damper, and the
    damper MuJoCo's step takes implicitly (under the implicit integrators; Euler's is explicit)."""

    moment: np.ndarray  # (nt, ndof)
    stiffness: np.ndarray  # (nt,)
    rest: np.ndarray  # (2, nt): lengthspring, low and high
    damping: np.ndarray  # (nt,)
    implicit_damping: np.ndarray  # (nt,)

    @classmethod
    def none(cls, ndof: int) -> TendonSprings:
        return cls(np.zeros((0, ndof)), np.zeros(0), np.zeros((2, 0)), np.zeros(0), np.zeros(0))


@dataclass
class SpatialLaw:
    """The spatial tendons the law carries (`plan/spatial_tendon.py`) and what acts on them: per actuator the tendon
    it pulls (an index into `tendons.tendons`; -1: none, its moment is the plan's constant one) and its gear; per
    tendon with a linear spring or damper its index, stiffness, rest lengths (a deadband between them) and damper,
    and the damper MuJoCo's step takes implicitly."""

    tendons: SpatialTendons
    actuator: np.ndarray  # (nu,)
    gear: np.ndarray  # (nu,)
    sprung: np.ndarray  # (k,)
    stiffness: np.ndarray
    rest: np.ndarray  # (2, k)
    damping: np.ndarray
    implicit_damping: np.ndarray
    # the tendons with a limit or frictionloss row (indices into `tendons.tendons`) and their rows, as a fixed
    # tendon's (`TendonRows`) but on a length and a Jacobian that change with the pose
    rowed: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    limits: JointLimits = field(default_factory=lambda: JointLimits.none(0))
    friction: JointFriction = field(default_factory=lambda: JointFriction.none(0))

    @classmethod
    def none(cls, nu: int) -> SpatialLaw:
        empty = np.zeros(0)
        return cls(
            SpatialTendons(), np.full(nu, -1), np.zeros(nu), np.zeros(0, int), empty, np.zeros((2, 0)), empty, empty
        )


@dataclass
class JointLimits:
    """MuJoCo's joint limit rows, per robot DoF (`limited` where its joint has one the law carries): each a soft
    one-sided row at the range's ends, active within `margin`, with MuJoCo's reference stiffness and damping
    (solreflimit, refsafe applied at the model's timestep), solimplimit (5, ndof) and the row's diagApprox (the DoF's
    invweight0)."""

    limited: np.ndarray  # (ndof,) bool
    range: np.ndarray  # (2, ndof)
    margin: np.ndarray
    stiffness: np.ndarray  # K
    damping: np.ndarray  # B
    solimp: np.ndarray  # (5, ndof): dmin, dmax, width, midpoint, power
    diag_approx: np.ndarray

    @classmethod
    def none(cls, ndof: int) -> JointLimits:
        row = np.zeros(ndof)
        return cls(
            np.zeros(ndof, bool), np.zeros((2, ndof)), row.copy(), row.copy(), row.copy(), np.zeros((5, ndof)), row
        )


@dataclass
class JointFriction:
    """MuJoCo's frictionloss rows, per robot DoF (`loss` zero where there is none): each a two-sided row whose force
    is held within +-loss, with reference acceleration -B v (solreffriction, refsafe applied) and weight
    D = imp / ((1 - imp) diagApprox), imp solimpfriction's at zero violation, diagApprox the DoF's invweight0."""

    loss: np.ndarray
    damping: np.ndarray  # B
    weight: np.ndarray  # D

    @classmethod
    def none(cls, ndof: int) -> JointFriction:
        return cls(np.zeros(ndof), np.zeros(ndof), np.zeros(ndof))


@dataclass
class TendonRows:
    """MuJoCo's limit and frictionloss rows of the fixed tendons over the robot's joints that have one: per tendon its
    moment over the DoFs (its coefficients: its length is moment @ q), and its rows as `JointLimits` and
    `JointFriction` hold a DoF's, on the tendon's length (solreflimit and solimplimit, solreffriction and
    solimpfriction, diagApprox the tendon's invweight0)."""

    moment: np.ndarray  # (nt, ndof)
    limits: JointLimits
    friction: JointFriction

    @classmethod
    def none(cls, ndof: int) -> TendonRows:
        return cls(np.zeros((0, ndof)), JointLimits.none(0), JointFriction.none(0))


@dataclass
class JointCouplings:
    """MuJoCo's equality rows between the robot's joints that the law carries (active at load): joint equalities
    between its hinges and slides, and tendon equalities between fixed tendons over them. Per row,
    L1 - L1_0 = poly(L2 - L2_0), each L a joint's position or a fixed tendon's length, linear in q (`first`, `second`:
    its coefficients over the DoFs, a zero row where there is no second: L1 - L1_0 = poly[0]), L_0 its value at
    qpos0; a soft two-sided row with solref's stiffness and damping (refsafe applied), solimp and diagApprox, the
    two's invweight0 summed (a DoF's or a tendon's)."""

    first: np.ndarray  # (rows, ndof)
    second: np.ndarray  # (rows, ndof)
    origin: np.ndarray  # (2, rows): L1_0 and L2_0
    poly: np.ndarray  # (5, rows): polycoef
    stiffness: np.ndarray  # K
    damping: np.ndarray  # B
    solimp: np.ndarray  # (5, rows)
    diag_approx: np.ndarray

    @classmethod
    def none(cls, ndof: int) -> JointCouplings:
        row = np.zeros(0)
        return cls(
            np.zeros((0, ndof)),
            np.zeros((0, ndof)),
            np.zeros((2, 0)),
            np.zeros((5, 0)),
            row,
            row.copy(),
            np.zeros((5, 0)),
            row.copy(),
        )


@dataclass
class Connects:
    """MuJoCo's connect rows the law carries (`carried_equalities`): per connect, each end's robot link and the anchor
    in that link's frame (a body fixed to the world: the robot's root link, fixed too, at the anchor's place in its
    frame); three soft two-sided rows on the anchors' separation r = p1 - p2, with solref's stiffness and damping
    (refsafe applied), solimp taken at |r| (MuJoCo's impedance of the connect as a whole) and the rows' diagApprox."""

    links: np.ndarray  # (n, 2) robot links
    points: np.ndarray  # (n, 2, 3) the anchors, each in its link's frame
    stiffness: np.ndarray  # K
    damping: np.ndarray  # B
    solimp: np.ndarray  # (5, n)
    diag_approx: np.ndarray  # (n, 3)
    equalities: list[int] = field(default_factory=list)  # MuJoCo's ids

    @classmethod
    def none(cls) -> Connects:
        return cls(
            np.zeros((0, 2), int), np.zeros((0, 2, 3)), np.zeros(0), np.zeros(0), np.zeros((5, 0)), np.zeros((0, 3))
        )


@dataclass
class Welds:
    """MuJoCo's weld rows the law carries (`carried_equalities`; given by body): per weld, each end's robot link and
    its point in that link's frame (body1's at relpose's position, body2's at the anchor, as MuJoCo places them), the
    relpose rotation (w, x, y, z) and torquescale; six soft two-sided rows (three on the points' separation, three on
    torquescale times the vector part of conj(q2) q1 relpose), solref's stiffness and damping, solimp taken at the six
    rows' length, and the rows' diagApprox."""

    links: np.ndarray  # (n, 2) robot links
    points: np.ndarray  # (n, 2, 3)
    relative: np.ndarray  # (n, 4)
    torquescale: np.ndarray  # (n,)
    stiffness: np.ndarray
    damping: np.ndarray
    solimp: np.ndarray  # (5, n)
    diag_approx: np.ndarray  # (n, 6)
    equalities: list[int] = field(default_factory=list)

    @classmethod
    def none(cls) -> Welds:
        return cls(
            np.zeros((0, 2), int),
            np.zeros((0, 2, 3)),
            np.zeros((0, 4)),
            np.zeros(0),
            np.zeros(0),
            np.zeros(0),
            np.zeros((5, 0)),
            np.zeros((0, 6)),
        )


@dataclass
class JointActuation:
    """The law's arrays: per actuator, its moment over the robot's active DoFs (`ndof` of them), per DoF, and what
    the law leaves out (`not_carried`)."""

    ndof: int
    moment: np.ndarray  # (nu, ndof): dL/dq, MuJoCo's (gear, times a fixed tendon's coefficients), constant here
    gain: np.ndarray
    bias: np.ndarray  # (3, nu): b0, b1, b2
    ctrl_range: np.ndarray  # (2, nu): -inf, inf where ctrl is not clamped
    force_range: np.ndarray  # (2, nu): -inf, inf where the force is not clamped
    joint_range: np.ndarray  # (2, ndof): each DoF's actuatorfrcrange, -inf, inf where it has none
    dynamics: np.ndarray  # per actuator: MuJoCo's dyntype (none, integrator, filter, filterexact)
    time_constant: np.ndarray  # per actuator: a filter's dynprm[0] (at least mjMINVAL), else 1
    act_range: np.ndarray  # (2, nu): actrange where actlimited, else -inf, inf
    act_early: np.ndarray  # per actuator: the force reads the step's next activation (actearly)
    stiffness: np.ndarray  # per DoF
    spring_ref: np.ndarray
    damping: np.ndarray  # per DoF: its damper
    implicit_damping: np.ndarray  # per DoF: the damper MuJoCo's step takes implicitly (none where eulerdamp is off)
    velocity_gain: np.ndarray  # per actuator: -b2, where MuJoCo's step takes its velocity term implicitly, else 0
    # (ndof, ndof): the DoF pairs on one chain of the tree (one moves the other), where MuJoCo's implicit step keeps
    # an actuator's velocity cross term; it drops those between DoFs on separate branches (the mass matrix's pattern)
    chained: np.ndarray
    springs: TendonSprings = field(default_factory=lambda: TendonSprings.none(0))
    limits: JointLimits = field(default_factory=lambda: JointLimits.none(0))
    friction: JointFriction = field(default_factory=lambda: JointFriction.none(0))
    couplings: JointCouplings = field(default_factory=lambda: JointCouplings.none(0))
    tendon_rows: TendonRows = field(default_factory=lambda: TendonRows.none(0))
    connects: Connects = field(default_factory=Connects.none)
    welds: Welds = field(default_factory=Welds.none)
    spatial: SpatialLaw = field(default_factory=lambda: SpatialLaw.none(0))
    # the robot links of the bodies compensated fully (gravcomp 1): PhysX's gravity off on them is MuJoCo's gravity
    # and its compensation at their centres of mass together
    weightless: list[int] = field(default_factory=list)
    not_carried: list[str] = field(default_factory=list)

    @property
    def drive_damping(self) -> np.ndarray:
        """Per DoF, the damping its PhysX drive holds: the diagonal of MuJoCo's implicit derivative where no clamp
        binds (the implicit dampers, each actuator's -b2 m^2, each tendon's implicit damper d m^2), its negative
        actuator terms left out (PhysX's damping cannot be negative)."""
        tendons = self.springs.implicit_damping @ self.springs.moment**2
        return np.maximum(self.velocity_gain, 0.0) @ self.moment**2 + tendons + self.implicit_damping


def plan_joint_actuation(
    model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int, link_of_body: dict[int, int] | None = None
) -> JointActuation | str:
    """The law for `model` whose MuJoCo joint j moves robot DoF `dof_of_joint[j]` (hinges and slides) and whose body
    b is robot link `link_of_body[b]`, or why the law cannot drive it (an actuator outside its scope)."""
    why = _outside(model, dof_of_joint, link_of_body or {})
    if why is not None:
        return why
    actuated = not mj.disabled(model, "actuation")
    affine = (model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)).astype(float)
    bias = (model.actuator_biasprm[:, :3] * affine[:, None]).T.copy() if model.nu else np.zeros((3, 0))
    gain = model.actuator_gainprm[:, 0].copy()
    off = ((int(model.opt.disableactuator) >> np.clip(model.actuator_group, 0, 30)) & 1).astype(bool) | (not actuated)
    gain[off], bias[:, off] = 0.0, 0.0  # actuation disabled, or the actuator's group (`disableactuator`)
    implicit = int(model.opt.integrator) not in EXPLICIT_ACTUATORS
    clamps = model.actuator_ctrllimited.astype(bool) & (not mj.disabled(model, "clampctrl"))
    ctrl_range = np.where(clamps, model.actuator_ctrlrange.T, [[-np.inf], [np.inf]])
    force_range = np.where(model.actuator_forcelimited.astype(bool), model.actuator_forcerange.T, [[-np.inf], [np.inf]])
    stiffness, spring_ref, damping, joint_range = _joint_arrays(model, dof_of_joint, ndof)
    damped_explicitly = mj.explicit_damping(model)
    moment = _moment(model, dof_of_joint, ndof)
    spatial = _spatial(model, link_of_body or {}, int(model.opt.integrator) not in EXPLICIT_ACTUATORS)
    moment[spatial.actuator >= 0] = 0.0  # their moment changes with the pose: the law's per step
    dynamics = model.actuator_dyntype.astype(np.int64)
    filtered = (dynamics == FILTER) | (dynamics == FILTEREXACT)
    time_constant = np.where(filtered, np.maximum(model.actuator_dynprm[:, 0], mj.MJMINVAL), 1.0)
    act_range = np.where(model.actuator_actlimited.astype(bool), model.actuator_actrange.T, [[-np.inf], [np.inf]])
    carried = carried_equalities(model, dof_of_joint)
    return JointActuation(
        ndof,
        moment,
        gain,
        bias,
        ctrl_range,
        force_range,
        joint_range,
        dynamics,
        time_constant,
        act_range,
        model.actuator_actearly.astype(bool),
        stiffness,
        spring_ref,
        damping,
        np.zeros(ndof) if damped_explicitly else damping,
        -bias[2] if implicit else np.zeros(model.nu),
        _chained(model, dof_of_joint, ndof),
        _tendon_springs(model, dof_of_joint, ndof, implicit),
        _joint_limits(model, dof_of_joint, ndof),
        _joint_friction(model, dof_of_joint, ndof),
        _joint_couplings(model, dof_of_joint, ndof, carried),
        _tendon_rows(model, dof_of_joint, ndof),
        _connects(model, carried, link_of_body or {}),
        _welds(model, carried, link_of_body or {}),
        spatial,
        _weightless(model, link_of_body or {}),
        _not_carried(model, link_of_body or {}, dof_of_joint, carried, spatial),
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


def robot_articulation(model: mujoco.MjModel, mapping: Mapping) -> int:
    """The articulation a ManiSkill agent takes for its robot: the one whose hinges and slides the most actuators
    drive (through a joint or a fixed tendon); in a model without such actuators, the one with the most DoFs; the
    first of a tie. A scene file's floor or table is a tree of its own, which can come before the robot's
    (tests/test_maniskill_joint_actuation.py::test_the_robot_is_the_tree_the_actuators_drive)."""
    driven = np.zeros(len(mapping.articulation_dofs))
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) not in TRANSMISSIONS:
            continue
        joints = _transmission_joints(model, a) or []
        for owner in {mapping.joints[j].articulation for j in joints if mapping.joints[j].drive_key is not None}:
            driven[owner] += 1
    score = driven if driven.any() else np.asarray(mapping.articulation_dofs, float)
    return int(np.argmax(score)) if score.size else 0


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


def _joint_limits(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> JointLimits:
    """The limit rows of the robot's limited hinges and slides, none where the model disables limits."""
    limits = JointLimits.none(ndof)
    if mj.disabled(model, "limit", "constraint"):
        return limits
    for joint, dof in dof_of_joint.items():
        if is_limited(model, joint):  # a range open at both ends limits nothing
            _limit_row(
                limits,
                dof,
                SoftRow.of(model, model.jnt_solref[joint], model.jnt_solimp[joint]),
                model.jnt_range[joint],
                model.jnt_margin[joint],
                model.dof_invweight0[model.jnt_dofadr[joint]],
            )
    return limits


def _limit_row(limits: JointLimits, owner: int, row: SoftRow, range_: np.ndarray, margin: float, diag: float) -> None:
    limits.limited[owner] = True
    limits.range[:, owner], limits.margin[owner] = range_, margin
    limits.stiffness[owner], limits.damping[owner] = row.stiffness, row.damping
    limits.solimp[:, owner] = row.solimp
    limits.diag_approx[owner] = diag


def _joint_friction(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> JointFriction:
    """The frictionloss rows of the robot's hinges and slides, none where the model disables frictionloss."""
    friction = JointFriction.none(ndof)
    if mj.disabled(model, "frictionloss", "constraint"):
        return friction
    for joint, dof in dof_of_joint.items():
        address = int(model.jnt_dofadr[joint])
        if model.dof_frictionloss[address] > 0:
            _friction_row(
                friction,
                dof,
                SoftRow.of(model, model.dof_solref[address], model.dof_solimp[address]),
                model.dof_frictionloss[address],
                model.dof_invweight0[address],
            )
    return friction


def _friction_row(friction: JointFriction, owner: int, row: SoftRow, loss: float, diag: float) -> None:
    """A frictionloss row: its weight at solimp's impedance at zero violation."""
    friction.loss[owner], friction.damping[owner] = loss, row.damping
    friction.weight[owner] = 1.0 / row.regularizer(row.impedance(0.0), float(diag))


def _tendons_with_rows(model: mujoco.MjModel) -> tuple[list[int], list[int]]:
    """The tendons with a limit row, and those with a frictionloss row, where the model does not disable them."""
    limited = [] if mj.disabled(model, "limit", "constraint") else np.flatnonzero(model.tendon_limited).tolist()
    rubbing = [] if mj.disabled(model, "frictionloss", "constraint") else np.flatnonzero(model.tendon_frictionloss > 0)
    return limited, list(rubbing)


def _tendon_rows(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> TendonRows:
    """The limit and frictionloss rows of the fixed tendons over the robot's joints that have one, none where the
    model disables them."""
    limited, rubbing = _tendons_with_rows(model)
    tendons = [t for t in sorted(set(limited) | set(rubbing)) if _fixed_over(model, t, dof_of_joint)]
    if not tendons:
        return TendonRows.none(ndof)
    return TendonRows(_tendon_moments(model, dof_of_joint, ndof, tendons), *_tendon_row_laws(model, tendons))


def _tendon_row_laws(model: mujoco.MjModel, tendons: list[int]) -> tuple[JointLimits, JointFriction]:
    """The limit and frictionloss rows of `tendons` where they have them (diagApprox the tendon's invweight0)."""
    limited, rubbing = _tendons_with_rows(model)
    limits, friction = JointLimits.none(len(tendons)), JointFriction.none(len(tendons))
    for owner, tendon in enumerate(tendons):
        diag = model.tendon_invweight0[tendon]
        if tendon in limited:
            row = SoftRow.of(model, model.tendon_solref_lim[tendon], model.tendon_solimp_lim[tendon])
            _limit_row(limits, owner, row, model.tendon_range[tendon], model.tendon_margin[tendon], diag)
        if tendon in rubbing:
            row = SoftRow.of(model, model.tendon_solref_fri[tendon], model.tendon_solimp_fri[tendon])
            _friction_row(friction, owner, row, model.tendon_frictionloss[tendon], diag)
    return limits, friction


def carried_equalities(model: mujoco.MjModel, dof_of_joint: dict[int, int]) -> list[int]:
    """The active equalities the law carries: joint equalities whose joints (both, or the one) are among the robot's
    hinges and slides, tendon equalities whose tendons are fixed over them, and connects (given by body or site) and
    welds (given by body) within the robot's tree: each end moved only by those joints and the free joint of the
    robot's root, if it has one (a gripper's linkage, a leg's rods on a floating body). A connect's end may instead be
    fixed to the world where the robot's root is fixed too."""
    if mj.disabled(model, "equality", "constraint"):
        return []
    joint, tendon = int(mujoco.mjtEq.mjEQ_JOINT), int(mujoco.mjtEq.mjEQ_TENDON)
    connect, weld = int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD)
    held = _loop_dofs(model, dof_of_joint)

    def carried(e: int) -> bool:
        kind, ends = int(model.eq_type[e]), (int(model.eq_obj1id[e]), int(model.eq_obj2id[e]))
        if kind == joint:
            return all(end < 0 or end in dof_of_joint for end in ends)
        if kind == tendon:
            return all(end < 0 or _fixed_over(model, end, dof_of_joint) for end in ends)
        if kind == connect or (kind == weld and int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_BODY)):
            bodies = _connect_bodies(model, e)
            moved = [mj.body_dofs(model, end) for end in bodies]
            if not all(dofs <= held for dofs in moved):
                return False
            if kind == weld:  # both ends on the robot's links
                return all(moved)
            # an end fixed to the world is placed on the other end's root, which must be fixed too
            roots = [mj.body_dofs(model, int(model.body_rootid[end])) for end in bodies]
            placed = all(dofs or not root for dofs, root in zip(moved, reversed(roots)))
            return placed and bool(moved[0] | moved[1])  # none between two fixed bodies: no rows
        return False

    return [e for e in range(model.neq) if model.eq_active0[e] and carried(e)]


def _loop_dofs(model: mujoco.MjModel, dof_of_joint: dict[int, int]) -> set[int]:
    """MuJoCo's DoFs that may move a carried loop's ends: the robot's hinges and slides, and the free joint of the
    robot's root body where it has one (the law moves that root as MuJoCo's free joint moves it, or holds it fixed
    where the robot's root link is)."""
    dofs = {d for d in range(model.nv) if int(model.dof_jntid[d]) in dof_of_joint}
    roots = {int(model.body_rootid[int(model.jnt_bodyid[j])]) for j in dof_of_joint}
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) == free and int(model.jnt_bodyid[j]) in roots:
            dofs.update(range(int(model.jnt_dofadr[j]), int(model.jnt_dofadr[j]) + 6))
    return dofs


def _joint_couplings(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int, carried: list[int]):
    """The carried couplings' rows (`carried_equalities`), each end as coefficients over the robot's DoFs."""
    kinds = (int(mujoco.mjtEq.mjEQ_JOINT), int(mujoco.mjtEq.mjEQ_TENDON))
    rows = [e for e in carried if int(model.eq_type[e]) in kinds]
    if not rows:
        return JointCouplings.none(ndof)
    joint = int(mujoco.mjtEq.mjEQ_JOINT)
    ends = [int(model.eq_obj1id[e]) for e in rows] + [int(model.eq_obj2id[e]) for e in rows]
    tendons = sorted({end for e, end in zip(rows * 2, ends) if end >= 0 and int(model.eq_type[e]) != joint})
    tendon_moment = dict(zip(tendons, _tendon_moments(model, dof_of_joint, ndof, tendons)))
    first, second = np.zeros((len(rows), ndof)), np.zeros((len(rows), ndof))
    origin, diag = [], []
    for k, e in enumerate(rows):
        ends, weights, zero = (int(model.eq_obj1id[e]), int(model.eq_obj2id[e])), [], []
        for coefficients, end in zip((first, second), ends):
            if end < 0:
                zero.append(0.0)
            elif int(model.eq_type[e]) == joint:
                coefficients[k, dof_of_joint[end]] = 1.0
                zero.append(model.qpos0[model.jnt_qposadr[end]])
                weights.append(model.dof_invweight0[model.jnt_dofadr[end]])
            else:
                coefficients[k] = tendon_moment[end]
                zero.append(model.tendon_length0[end])
                weights.append(model.tendon_invweight0[end])
        origin.append(zero)
        diag.append(sum(weights))
    poly = np.array([model.eq_data[e][:5] for e in rows], float).T
    return JointCouplings(first, second, np.array(origin, float).T, poly, *_soft_laws(model, rows), np.array(diag))


def _connects(model: mujoco.MjModel, carried: list[int], link_of_body: dict[int, int]) -> Connects:
    """The carried connects' rows (`carried_equalities`), each end on its robot link; an end fixed to the world is
    placed on the robot's root link, fixed too, from MuJoCo's poses at qpos0 (the env may place the robot anywhere)."""
    connect = int(mujoco.mjtEq.mjEQ_CONNECT)
    rows = [e for e in carried if int(model.eq_type[e]) == connect]
    if not rows or not link_of_body:
        return Connects.none()
    data = mj.forward_at(model, all_equalities=True)  # qpos0's poses, and every equality's rows for diagApprox
    links, points = [], []
    for e in rows:
        bodies, ends = _connect_bodies(model, e), []
        if int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):  # each anchor the site, in its body's frame
            anchors = tuple(model.site_pos[int(site)] for site in (model.eq_obj1id[e], model.eq_obj2id[e]))
        else:
            anchors = (model.eq_data[e][0:3], model.eq_data[e][3:6])
        for end, anchor, other in zip(bodies, anchors, reversed(bodies)):
            if not mj.body_dofs(model, end):  # fixed to the world: the same point on the other end's root
                root = int(model.body_rootid[other])
                world = data.xpos[end] + data.xmat[end].reshape(3, 3) @ anchor
                anchor, end = data.xmat[root].reshape(3, 3).T @ (world - data.xpos[root]), root
            ends.append((link_of_body[end], anchor))
        links.append([link for link, _ in ends])
        points.append([anchor for _, anchor in ends])
    return Connects(np.array(links, int), np.array(points, float), *_soft_rows(model, data, rows), rows)


def _welds(model: mujoco.MjModel, carried: list[int], link_of_body: dict[int, int]) -> Welds:
    """The carried welds' rows (`carried_equalities`), each end on its robot link."""
    weld = int(mujoco.mjtEq.mjEQ_WELD)
    rows = [e for e in carried if int(model.eq_type[e]) == weld]
    if not rows or not link_of_body:
        return Welds.none()
    data = mj.forward_at(model, all_equalities=True)  # every equality's rows, for diagApprox
    body1, body2 = (int(model.eq_obj1id[e]) for e in rows), (int(model.eq_obj2id[e]) for e in rows)
    return Welds(
        np.array([[link_of_body[a], link_of_body[b]] for a, b in zip(body1, body2)], int),
        np.array([[model.eq_data[e][3:6], model.eq_data[e][0:3]] for e in rows], float),  # relpose's, the anchor
        np.array([model.eq_data[e][6:10] for e in rows], float),  # body2's rotation in body1's frame
        np.array([model.eq_data[e][10] for e in rows], float),
        *_soft_rows(model, data, rows),
        rows,
    )


def _soft_laws(model: mujoco.MjModel, rows: list[int]) -> tuple[np.ndarray, ...]:
    """Per equality of `rows`: solref's stiffness and damping (refsafe applied) and solimp (5, n)."""
    laws = [SoftRow.of(model, model.eq_solref[e], model.eq_solimp[e]) for e in rows]
    return (
        np.array([law.stiffness for law in laws]),
        np.array([law.damping for law in laws]),
        np.array([law.solimp for law in laws], float).T,
    )


def _soft_rows(model: mujoco.MjModel, data: mujoco.MjData, rows: list[int]) -> tuple[np.ndarray, ...]:
    """Per equality of `rows`: its soft law (`_soft_laws`) and its rows' diagApprox from `data`'s forward pass (n,
    rows each)."""
    diag = [diag_approx(model, data, int(mujoco.mjtConstraint.mjCNSTR_EQUALITY), e) for e in rows]
    return (*_soft_laws(model, rows), np.array(diag, float))


def _connect_bodies(model: mujoco.MjModel, e: int) -> tuple[int, int]:
    """A connect's two bodies: given by body, or the bodies of its two sites."""
    ends = (int(model.eq_obj1id[e]), int(model.eq_obj2id[e]))
    if int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
        return tuple(int(model.site_bodyid[site]) for site in ends)
    return ends


def _fixed_over(model: mujoco.MjModel, tendon: int, dof_of_joint: dict[int, int]) -> bool:
    """Whether a tendon is fixed over the robot's hinges and slides (every wrap one of its joints)."""
    wraps = range(int(model.tendon_adr[tendon]), int(model.tendon_adr[tendon] + model.tendon_num[tendon]))
    return all(int(model.wrap_type[w]) == JOINT_WRAP and int(model.wrap_objid[w]) in dof_of_joint for w in wraps)


def _tendon_moments(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int, tendons: list[int]) -> np.ndarray:
    """The tendons' moments (len(tendons), ndof) over the robot's DoFs from MuJoCo's tendon pass at qpos0: constant
    for a fixed tendon, its coefficients."""
    data = mujoco.MjData(model)
    mujoco.mj_fwdPosition(model, data)
    dense = np.zeros((model.ntendon, model.nv))
    mujoco.mju_sparse2dense(dense, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
    moment = np.zeros((len(tendons), ndof))
    for joint, robot_dof in dof_of_joint.items():
        moment[:, robot_dof] = dense[tendons, model.jnt_dofadr[joint]]
    return moment


def _carried_tendons(model: mujoco.MjModel, dof_of_joint: dict[int, int]) -> list[int]:
    """The tendons the law carries: fixed over the robot's hinges and slides, with a spring or a damper, linear (no
    polynomial term) and with no armature."""
    return [t for t in range(model.ntendon) if _linear_spring(model, t) and _fixed_over(model, t, dof_of_joint)]


def _linear_spring(model: mujoco.MjModel, tendon: int) -> bool:
    """Whether a tendon has a spring or a damper the law carries: linear (no polynomial term), with no armature."""
    sprung = model.tendon_stiffness[tendon] or model.tendon_damping[tendon]
    linear = not (np.any(model.tendon_stiffnesspoly[tendon]) or np.any(model.tendon_dampingpoly[tendon]))
    return bool(sprung and linear and not model.tendon_armature[tendon])


def _spring_arrays(model: mujoco.MjModel, tendons: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tendons' stiffness, rest lengths (2, n) and damping, zero where the model disables springs or dampers."""
    stiffness = 0.0 if mj.disabled(model, "spring") else model.tendon_stiffness[tendons]
    damping = 0.0 if mj.disabled(model, "damper") else model.tendon_damping[tendons]
    rest = model.tendon_lengthspring[tendons].T.copy()
    return stiffness + np.zeros(len(tendons)), rest, damping + np.zeros(len(tendons))


def _tendon_springs(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int, implicit: bool) -> TendonSprings:
    """The carried tendons' springs and dampers (`_carried_tendons`), their moments from MuJoCo's tendon pass at
    qpos0 (constant for a fixed tendon)."""
    tendons = _carried_tendons(model, dof_of_joint)
    if not tendons:
        return TendonSprings.none(ndof)
    stiffness, rest, damping = _spring_arrays(model, tendons)
    moment = _tendon_moments(model, dof_of_joint, ndof, tendons)
    return TendonSprings(moment, stiffness, rest, damping, damping * implicit)


def _spatial(model: mujoco.MjModel, link_of_body: dict[int, int], implicit: bool) -> SpatialLaw:
    """The spatial tendons the actuators pull, and those with a linear spring or damper and no armature, wherever
    the law can carry them (`why_outside`)."""
    if not link_of_body:
        return SpatialLaw.none(model.nu)
    spatial = [
        t
        for t in range(model.ntendon)
        if model.tendon_num[t]
        and int(model.wrap_type[model.tendon_adr[t]]) != JOINT_WRAP
        and why_outside(model, t, link_of_body) is None
    ]
    tendon = int(mujoco.mjtTrn.mjTRN_TENDON)
    pulled = [
        int(model.actuator_trnid[a, 0]) if int(model.actuator_trntype[a]) == tendon else -1 for a in range(model.nu)
    ]
    linear = [t for t in spatial if _linear_spring(model, t)]
    limited, rubbing = _tendons_with_rows(model)
    rowed = [t for t in spatial if t in limited or t in rubbing]
    tendons = [t for t in spatial if t in pulled or t in linear or t in rowed]
    if not tendons:
        return SpatialLaw.none(model.nu)
    index = {t: k for k, t in enumerate(tendons)}
    stiffness, rest, damping = _spring_arrays(model, linear)
    return SpatialLaw(
        plan_spatial_tendons(model, tendons, link_of_body),
        np.array([index.get(t, -1) for t in pulled], int),
        model.actuator_gear[:, 0].copy(),
        np.array([index[t] for t in linear], int),
        stiffness,
        rest,
        damping,
        damping * implicit,
        np.array([index[t] for t in rowed], int),
        *_tendon_row_laws(model, rowed),
    )


def _chained(model: mujoco.MjModel, dof_of_joint: dict[int, int], ndof: int) -> np.ndarray:
    """(ndof, ndof): whether two robot DoFs lie on one chain of MuJoCo's tree (each DoF is on its own)."""
    dof_of = {int(model.jnt_dofadr[joint]): robot_dof for joint, robot_dof in dof_of_joint.items()}
    chained = np.eye(ndof, dtype=bool)
    for dof, robot_dof in dof_of.items():
        above = int(model.dof_parentid[dof])
        while above >= 0:
            if above in dof_of:
                chained[robot_dof, dof_of[above]] = chained[dof_of[above], robot_dof] = True
            above = int(model.dof_parentid[above])
    return chained


def _weightless(model: mujoco.MjModel, link_of_body: dict[int, int]) -> list[int]:
    """The links of the fully compensated bodies, where the compensation is a passive force (not routed through the
    actuators, `actuatorgravcomp`) and gravity is on."""
    if np.any(model.jnt_actgravcomp) or mj.disabled(model, "gravity"):
        return []
    return sorted(link for body, link in link_of_body.items() if model.body_gravcomp[body] == 1.0)


def _outside(model: mujoco.MjModel, dof_of_joint: dict[int, int], link_of_body: dict[int, int]) -> str | None:
    """Why an actuator is outside the law's scope, naming it; None where every one is inside."""
    for a in range(model.nu):
        name = mj.name(model, "actuator", a)
        if int(model.actuator_trntype[a]) not in TRANSMISSIONS:
            return f"actuator {name!r} drives a site, body or slider-crank, not a joint or tendon"
        joints = _transmission_joints(model, a)
        if joints is None:
            tendon = int(model.actuator_trnid[a, 0])
            why = why_outside(model, tendon, link_of_body) if link_of_body else "no robot links are known"
            if why is not None:
                return f"actuator {name!r} drives a spatial tendon the law cannot carry: {why}"
            joints = []
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


# the law takes a floating root's step from MuJoCo's rows where every force on the tree is its own
FLOATING_ROOT = "a floating root's step where a contact pushed the tree: PhysX's, which conserves its momentum"
FREE_JOINT_TERMS = "a free joint's damping, armature or frictionloss"  # the root rows hold none of them
OTHER_EQUALITIES = "equality constraints other than couplings, and connects and welds within the robot's tree"


def _planned_equalities(model: mujoco.MjModel, carried: list[int], link_of_body: dict[int, int]) -> list:
    """The equalities the plan holds: the carried ones, but a loop where no robot link is known (`_connects`)."""
    loops = (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD))
    return carried if link_of_body else [e for e in carried if int(model.eq_type[e]) not in loops]


def _not_carried(
    model: mujoco.MjModel,
    link_of_body: dict[int, int],
    dof_of_joint: dict[int, int],
    carried: list[int],
    spatial: SpatialLaw | None = None,
) -> list[str]:
    """What MuJoCo's model holds beyond the law and the build: each is PhysX's own or absent on this path."""
    sprung = int(np.count_nonzero((model.tendon_stiffness != 0) | (model.tendon_damping != 0)))
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    roots = [
        j for j in range(model.njnt) if int(model.jnt_type[j]) == free and int(model.jnt_bodyid[j]) in link_of_body
    ]
    root_dofs = [int(model.jnt_dofadr[j]) + k for j in roots for k in range(6)]
    checks = [
        (bool(roots), FLOATING_ROOT),
        (
            any(np.any(getattr(model, f"dof_{name}")[root_dofs]) for name in ("damping", "armature", "frictionloss")),
            FREE_JOINT_TERMS,
        ),
        (bool(model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_OVERRIDE), "the override flag's solref and solimp"),
        (
            sprung > len(_carried_tendons(model, dof_of_joint)) + len(spatial.sprung if spatial else ()),
            "the springs and dampers of a nonlinear tendon, of one with armature or of a spatial one outside the law",
        ),
        (
            any(
                not _fixed_over(model, t, dof_of_joint) and t not in (spatial.tendons.tendons if spatial else ())
                for rows in _tendons_with_rows(model)
                for t in rows
            ),
            "the limits and frictionloss of a spatial tendon outside the law or of one over joints outside the robot",
        ),
        (
            bool(model.neq)
            and not mj.disabled(model, "equality", "constraint")
            and len(_planned_equalities(model, carried, link_of_body)) < int(np.count_nonzero(model.eq_active0)),
            OTHER_EQUALITIES,
        ),
        (np.any((model.body_gravcomp != 0) & (model.body_gravcomp != 1)), "partial gravity compensation"),
        (np.any(model.jnt_actgravcomp) and np.any(model.body_gravcomp), "gravity compensation through the actuators"),
        (model.opt.density > 0 or model.opt.viscosity > 0, "fluid forces"),
        (int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_IMPLICIT), "the implicit integrator's Coriolis"),
    ]
    return [what for present, what in checks if present]
