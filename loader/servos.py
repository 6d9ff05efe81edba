"""Joint-space PD servos read off a model's actuators: what ManiSkill's PD controllers need to drive the robot as
MuJoCo's position and velocity servos do.

An affine servo (force = gain ctrl + b0 + b1 L + b2 dL/dt, MuJoCo's position: b1 = -kp, b2 = -kv) on a joint with
gear g is a PhysX drive with stiffness g² kp and damping g² kv plus the joint's own damping, aimed at
(gain ctrl + b0) / (kp g). On a fixed tendon L = sum c_i q_i whose joints are tied to one of them, x, by joint
equalities (q_i = m_i x + o_i, MuJoCo's linear polycoef), it is ManiSkill's mimic controller on x: the target
x* = ((gain ctrl + b0) / (kp g) - sum c_i o_i) / S with S = sum c_i m_i, and joint i's drive g² c_i kp S / m_i, which
gives each joint MuJoCo's force on the coupled motion
(tests/test_maniskill.py::test_an_arm_holds_its_keyframe_under_zero_delta_actions_as_in_mujoco)."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from .model.drive import DofDrive

UNLIMITED = 1e10  # ManiSkill's force limit for "none"


@dataclass
class Servo:
    """One actuator as a PD drive over `joints` (the driven joint first, then the joints that mimic it)."""

    actuator: str
    kind: str  # "position" or "velocity"
    joints: list[str]
    stiffness: list[float]
    damping: list[float]
    force_limit: list[float]
    lower: float | None  # the driven joint's target (position or velocity) at the ends of ctrlrange
    upper: float | None
    mimic: dict[str, dict] = field(default_factory=dict)  # ManiSkill's: joint -> {"joint", "multiplier", "offset"}
    index: int = -1  # the actuator's
    slope: float = 0.0  # the driven joint's target is slope ctrl + intercept
    intercept: float = 0.0

    def target(self, ctrl: float) -> float:
        """The driven joint's drive target (position or velocity) for the actuator's ctrl."""
        return self.slope * ctrl + self.intercept

    def physx_damping(self, timestep: float) -> list[float]:
        """Per joint, the drive damping whose implicit PhysX drive gives over one step the force of MuJoCo's servo,
        kp explicit and kv implicit: the loader's own drive law (`DofDrive.physx_damping`)."""
        return [DofDrive(k, d).physx_damping(timestep) for k, d in zip(self.stiffness, self.damping)]


@dataclass
class Motor:
    """A direct-force actuator on one joint: ManiSkill's default PD gains drive that joint, within the torque
    MuJoCo's motor can give it (|gear| times the largest force its forcerange and ctrlrange allow)."""

    actuator: str
    joint: str
    force_limit: float


def is_motor(act) -> bool:
    """Whether an actuator (an `ActuatorMap`) is a mapped motor on a hinge or slide: a gain, no bias, no dynamics."""
    return act.mapped and act.joint is not None and act.dynamics == "none" and not any(act.bias) and act.gain != 0


def motors(result) -> list[Motor]:
    """The mapped motors (`is_motor`) on hinge and slide joints."""
    model = result.model
    out = []
    for a, act in enumerate(result.actuators):
        if not is_motor(act):
            continue
        j = int(model.actuator_trnid[a, 0])
        target = result.mapping.joints[j]
        limits = [max(abs(x) for x in act.forcerange)] if act.forcerange is not None else []
        limits += [abs(act.gain) * max(abs(x) for x in act.ctrlrange)] if act.ctrlrange is not None else []
        out.append(
            Motor(
                act.name,
                result.articulations[target.articulation].active_joints[target.dofs[0]].name,
                abs(act.gear) * min(limits) if limits else UNLIMITED,
            )
        )
    return out


def _couplings(model: mujoco.MjModel) -> dict[int, tuple[int, float, float]]:
    """Dependent joint -> (independent joint, multiplier, offset) of each active linear joint equality."""
    out = {}
    for e in range(model.neq):
        poly = model.eq_data[e][:5]
        if (
            int(model.eq_type[e]) != mujoco.mjtEq.mjEQ_JOINT
            or not model.eq_active0[e]
            or model.eq_obj2id[e] < 0
            or np.any(poly[2:] != 0)
        ):
            continue
        y, x = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        y0, x0 = model.qpos0[model.jnt_qposadr[y]], model.qpos0[model.jnt_qposadr[x]]
        out[y] = (x, float(poly[1]), float(y0 + poly[0] - poly[1] * x0))
    return out


def _tendon_joints(model: mujoco.MjModel, tendon: int) -> list[tuple[int, float]]:
    start = int(model.tendon_adr[tendon])
    return [
        (int(model.wrap_objid[w]), float(model.wrap_prm[w])) for w in range(start, start + model.tendon_num[tendon])
    ]


def derive(result) -> list[Servo]:
    """The position and velocity servos among `result`'s actuators (a core `LoadResult`) that map onto joint
    drives; the rest (motors, dynamics, other transmissions) have none."""
    model = result.model
    names = {
        j: result.articulations[result.mapping.joints[j].articulation]
        .active_joints[result.mapping.joints[j].dofs[0]]
        .name
        for j in range(model.njnt)
        if result.mapping.joints[j].dofs
    }
    couplings = _couplings(model)
    servos = []
    for a, act in enumerate(result.actuators):
        b0, b1, b2 = act.bias
        kind = "position" if b1 < 0 else "velocity" if b1 == 0 and b2 < 0 else None
        if not act.mapped or act.moment or act.dynamics != "none" or kind is None or act.gain <= 0:
            continue  # a site's or slider-crank's moment changes with the pose: no drive holds it
        gain_of = -b1 if kind == "position" else -b2  # what turns the target into force
        trn = int(model.actuator_trnid[a, 0])
        if act.joint is None and kind == "velocity":
            continue
        if act.joint is not None:
            terms, control, offset_sum, scale = [(trn, 1.0, 1.0)], trn, 0.0, 1.0
        else:
            wraps = _tendon_joints(model, trn)
            free = [j for j, _ in wraps if j not in couplings]
            if len(free) != 1 or any(j != free[0] and couplings[j][0] != free[0] for j, _ in wraps):
                continue
            control = free[0]
            terms = [(j, c, 1.0 if j == control else couplings[j][1]) for j, c in wraps]
            offset_sum = sum(c * (0.0 if j == control else couplings[j][2]) for j, c in wraps)
            scale = sum(c * m for _, c, m in terms)
        g = act.gear
        per_joint = [g * g * c * scale / m for _, c, m in terms]
        if any(k <= 0 for k in per_joint) or scale == 0:
            continue
        limit = max(abs(x) for x in act.forcerange) if act.forcerange is not None else None
        slope, intercept = act.gain / (gain_of * g * scale), (b0 / (gain_of * g) - offset_sum) / scale
        ordered = sorted(terms, key=lambda t: t[0] != control)  # the driven joint first
        dof_damping = [float(model.dof_damping[model.jnt_dofadr[j]]) for j, _, _ in ordered]
        if kind == "velocity":  # one joint: the drive's damping holds the joint's too, so its target is scaled
            actuator_damping = per_joint[0] * -b2
            if act.ctrlrange is None:
                dof_damping = [0.0]  # unscalable without normalized actions: the joint's damping is not carried
            share = actuator_damping / (actuator_damping + dof_damping[0])
            slope, intercept = slope * share, intercept * share
        ends = sorted(slope * c + intercept for c in act.ctrlrange) if act.ctrlrange is not None else [None, None]
        servos.append(
            Servo(
                actuator=act.name,
                kind=kind,
                joints=[names[j] for j, _, _ in ordered],
                stiffness=[k * -b1 for k in _in_order(per_joint, terms, ordered)]
                if kind == "position"
                else [0.0] * len(terms),
                damping=[k * -b2 + d for k, d in zip(_in_order(per_joint, terms, ordered), dof_damping)],
                force_limit=[abs(g * c) * limit if limit is not None else UNLIMITED for _, c, _ in ordered],
                lower=ends[0],
                upper=ends[1],
                mimic={
                    names[j]: {"joint": names[control], "multiplier": couplings[j][1], "offset": couplings[j][2]}
                    for j, _, _ in ordered
                    if j != control
                },
                index=a,
                slope=slope,
                intercept=intercept,
            )
        )
    return servos


def _in_order(values: list[float], terms: list, ordered: list) -> list[float]:
    return [values[terms.index(t)] for t in ordered]
