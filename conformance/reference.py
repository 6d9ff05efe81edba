"""MuJoCo as the reference: a copy of the model with settings PhysX can match, and rollouts on it."""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from loader.model import mj

from .data_pool import borrowed

_INT = mujoco.mjtIntegrator
# PhysX integrates semi-implicitly with implicit drives: RK4 has no counterpart, Euler/implicitfast do.
_MATCHED_INTEGRATOR = {_INT.mjINT_RK4: _INT.mjINT_EULER, _INT.mjINT_IMPLICIT: _INT.mjINT_IMPLICITFAST}


def matched(model: mujoco.MjModel, contact: bool, actuation: bool = False) -> tuple[mujoco.MjModel, dict]:
    """A copy of `model` whose integrator PhysX can match (and contacts off if asked); with the settings.

    Without `actuation` (the dynamics tiers command generalized forces) MuJoCo's actuators are disabled, as the
    harness disables them in SAPIEN. With it (the actuated tiers) they stay on. Either way MuJoCo integrates
    with the model's own integrator, or the one PhysX can follow (RK4 -> Euler, implicit -> implicitfast): the
    loader applies actuator kv implicitly under implicitfast and explicitly under Euler, as MuJoCo does."""
    ref = copy.deepcopy(model)
    authored = _INT(int(model.opt.integrator))
    ref.opt.integrator = int(_MATCHED_INTEGRATOR.get(authored, authored))
    if not actuation:
        ref.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    if not contact:
        ref.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return ref, settings(model, ref)


def settings(model: mujoco.MjModel, ref: mujoco.MjModel) -> dict:
    return {
        "timestep": float(ref.opt.timestep),
        "gravity": [float(g) for g in ref.opt.gravity],
        "integrator_authored": _INT(int(model.opt.integrator)).name,
        "integrator_reference": _INT(int(ref.opt.integrator)).name,
        "solver": mujoco.mjtSolver(int(ref.opt.solver)).name,
        "contacts": not contacts_disabled(ref),
        "limits": not limits_disabled(ref),
        "actuators": not bool(ref.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)),
    }


def contacts_disabled(model: mujoco.MjModel) -> bool:
    """MuJoCo computes no contact: `<flag contact="disable"/>` or `<flag constraint="disable"/>`."""
    return mj.disabled(model, "contact", "constraint")


def limits_disabled(model: mujoco.MjModel) -> bool:
    """MuJoCo enforces no joint limit: `<flag limit="disable"/>` or `<flag constraint="disable"/>`."""
    return mj.disabled(model, "limit", "constraint")


def limited_dofs(model: mujoco.MjModel) -> list[tuple[int, int, float, float]]:
    """(joint, qpos address, lower, upper) of every limited hinge or slide joint."""
    out = []
    for j in range(model.njnt):
        if (
            model.jnt_limited[j]
            and not limits_disabled(model)
            and int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        ):
            out.append((j, int(model.jnt_qposadr[j]), float(model.jnt_range[j][0]), float(model.jnt_range[j][1])))
    return out


def initial_state(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, str]:
    """The start of every rollout: keyframe 0 if the model has one, else qpos0, as the model has it, a joint
    past its range included (hopper's qpos0 violates its foot limit): MuJoCo's soft limit pushes it back, and so
    must the loader."""
    if model.nkey:
        qpos, qvel, origin = model.key_qpos[0].copy(), model.key_qvel[0].copy(), "keyframe 0"
    else:
        qpos, qvel, origin = model.qpos0.copy(), np.zeros(model.nv), "qpos0"
    settled, before, after = settle_equalities(model, qpos)
    if after < before:
        qpos = settled
        origin += f" (settled onto its equality constraints: violation {before:.1e} -> {after:.1e})"
    return qpos, qvel, origin


def equality_violation(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    rows = data.efc_type[: data.nefc] == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    return float(np.abs(data.efc_pos[: data.nefc][rows]).max()) if rows.any() else 0.0


def settle_equalities(model: mujoco.MjModel, qpos: np.ndarray, steps: int = 2000) -> tuple[np.ndarray, float, float]:
    """A start that satisfies the model's equality constraints: MuJoCo steps from `qpos` with gravity, actuation
    and contact off and the velocity zeroed every step, so that only the constraints move it. A start that
    violates a loop (robotiq 2f85: 2e-3 m after moving joints inside their limits) is pulled back on the first step
    by MuJoCo's soft constraint and snapped by PhysX's rigid joint: the comparison would judge that, not the model.
    Returns (qpos, violation before, violation after); no equalities: the start unchanged."""
    flags = mujoco.mjtDisableBit
    if not model.neq or model.opt.disableflags & (int(flags.mjDSBL_EQUALITY) | int(flags.mjDSBL_CONSTRAINT)):
        return qpos, 0.0, 0.0
    work = copy.copy(model)  # the caller's model keeps its options
    work.opt.disableflags |= int(flags.mjDSBL_GRAVITY) | int(flags.mjDSBL_ACTUATION) | int(flags.mjDSBL_CONTACT)
    data = mujoco.MjData(work)
    data.qpos[:] = qpos
    mujoco.mj_forward(work, data)
    before = equality_violation(work, data)
    if before == 0.0:
        return qpos, 0.0, 0.0
    for _ in range(steps):
        data.qvel[:] = 0.0
        mujoco.mj_step(work, data)
    data.qvel[:] = 0.0
    mujoco.mj_forward(work, data)
    return data.qpos.copy(), before, equality_violation(work, data)


def qpos_difference(model: mujoco.MjModel, qpos_a: np.ndarray, qpos_b: np.ndarray) -> np.ndarray:
    """b - a in velocity space (nv), quaternion joints as rotation vectors; rows for 2-D inputs."""
    a, b = np.atleast_2d(qpos_a), np.atleast_2d(qpos_b)
    out = np.zeros((a.shape[0], model.nv))
    for i in range(a.shape[0]):
        mujoco.mj_differentiatePos(model, out[i], 1.0, a[i].astype(float), b[i].astype(float))
    return out if np.ndim(qpos_a) == 2 else out[0]


def position_scale(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Per row and dof (T, nv): the size of the coordinate a dof integrates, |q| for hinges and slides and |x| for
    a free joint's position, 1 for rotations kept as quaternions; float32 resolves it to about 6e-8 of that."""
    qpos = np.atleast_2d(qpos)
    out = np.ones((qpos.shape[0], model.nv))
    for j in range(model.njnt):
        adr, dof, kind = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]), int(model.jnt_type[j])
        if kind in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            out[:, dof] = np.abs(qpos[:, adr])
        elif kind == int(mujoco.mjtJoint.mjJNT_FREE):
            out[:, dof : dof + 3] = np.abs(qpos[:, adr : adr + 3])
    return out


def body_poses(data: mujoco.MjData) -> np.ndarray:
    """World pose of every body as (nbody, 7): x, y, z, qw, qx, qy, qz."""
    return np.concatenate([data.xpos, data.xquat], axis=1)


@dataclass
class Rollout:
    """States before each step (T+1 rows) and the generalized force applied at each step (T rows); with a
    ctrl sequence also the ctrl MuJoCo applied (after its clamp) and `data.actuator_force` at each step."""

    qpos: np.ndarray
    qvel: np.ndarray
    command: np.ndarray
    body_pose: np.ndarray  # (T+1, nbody, 7)
    ctrl: np.ndarray | None = None  # (T, nu) as given
    actuator_force: np.ndarray | None = None  # (T, nu) actuator-space force of each step
    act: np.ndarray | None = None  # (T+1, na) activations before each step (they start at zero)
    unstable_step: int | None = None  # the first step after which MuJoCo reported a blow-up (bad qacc)
    contacts: np.ndarray | None = None  # (T,) MuJoCo's contacts at each step's start (`data.ncon`)

    def unstable(self, model: mujoco.MjModel) -> str | None:
        """Why this run is no reference (None when it is one): MuJoCo blew up (and reset its state) on it."""
        if self.unstable_step is None:
            return None
        integrator = mujoco.mjtIntegrator(int(model.opt.integrator)).name.removeprefix("mjINT_")
        return (
            f"MuJoCo's own rollout is unstable under {integrator} (bad qacc at step {self.unstable_step}): "
            "no reference to compare"
        )


Policy = Callable[[int, np.ndarray, np.ndarray], np.ndarray]


def step_from(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    qvel: np.ndarray,
    act: np.ndarray | None = None,
    ctrl: np.ndarray | None = None,
    qfrc: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's next (qpos, qvel) from exactly this state: a one-step comparison starts both simulators from the
    state SAPIEN holds (float32), so that a constraint row switching on at a boundary sees the same state."""
    with borrowed(model) as data:
        data.qpos[:], data.qvel[:] = qpos, qvel
        if act is not None and model.na:
            data.act[:] = act
        if ctrl is not None and model.nu:
            data.ctrl[:] = ctrl
        if qfrc is not None:
            data.qfrc_applied[:] = qfrc
        mujoco.mj_step(model, data)
        return data.qpos.copy(), data.qvel.copy()


def rollout(
    model: mujoco.MjModel,
    qpos0: np.ndarray,
    qvel0: np.ndarray,
    steps: int,
    command: np.ndarray | Policy | None = None,
    ctrl: np.ndarray | None = None,
) -> Rollout:
    """Step MuJoCo from (qpos0, qvel0); `command` is a (steps, nv) array or a policy(step, qpos, qvel);
    `ctrl` (steps, nu) is written to `data.ctrl` before each step."""
    with borrowed(model) as data:
        data.qpos[:], data.qvel[:] = qpos0, qvel0
        mujoco.mj_forward(model, data)
        qpos = np.zeros((steps + 1, model.nq))
        qvel = np.zeros((steps + 1, model.nv))
        poses = np.zeros((steps + 1, model.nbody, 7))
        applied = np.zeros((steps, model.nv))
        force = np.zeros((steps, model.nu)) if ctrl is not None else None
        act = np.zeros((steps + 1, model.na))
        contacts = np.zeros(steps, dtype=int)
        unstable_step = None
        bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
        for t in range(steps + 1):
            if t:  # mj_step leaves xpos/xquat at the state before the step: bring them to the new state
                mujoco.mj_kinematics(model, data)
            qpos[t], qvel[t], poses[t], act[t] = data.qpos, data.qvel, body_poses(data), data.act
            if t == steps:
                break
            if command is None:
                tau = np.zeros(model.nv)
            elif callable(command):
                tau = command(t, data.qpos.copy(), data.qvel.copy())
            else:
                tau = command[t]
            applied[t] = tau
            data.qfrc_applied[:] = tau
            if ctrl is not None:
                data.ctrl[:] = ctrl[t]
            mujoco.mj_step(model, data)
            contacts[t] = data.ncon  # found by mj_step at the state before the step
            if force is not None:  # computed by mj_step from the state before the step
                force[t] = data.actuator_force
            if unstable_step is None and (data.warning[bad].number or not np.all(np.isfinite(data.qacc))):
                unstable_step = t
        ctrl = None if ctrl is None else np.asarray(ctrl)
        return Rollout(qpos, qvel, applied, poses, ctrl, force, act, unstable_step, contacts)
