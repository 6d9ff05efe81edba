"""Joint commands generated deterministically from the seed, identical for both simulators.

Every command is a generalized force (nv); dofs of free joints (floating roots) get none, since SAPIEN
cannot be commanded there through `set_qf`."""

from __future__ import annotations

import zlib

import mujoco
import numpy as np

from .data_pool import borrowed
from .reference import limited_dofs

_HINGE_SLIDE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


def rng(seed: int, *tags: str) -> np.random.Generator:
    """A generator keyed by the seed and a purpose, so adding a command never reshuffles another."""
    return np.random.default_rng([seed] + [zlib.crc32(t.encode()) for t in tags])


def actuated_dofs(model: mujoco.MjModel) -> np.ndarray:
    """Boolean mask over dofs that take a command: hinge and slide joints."""
    mask = np.zeros(model.nv, dtype=bool)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in _HINGE_SLIDE:
            mask[model.jnt_dofadr[j]] = True
    return mask


def dof_inertia(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Effective inertia 1 / (M^-1)_ii of each dof at qpos: the torque giving unit acceleration on that dof
    alone (scales commands so that light and heavy dofs move comparably)."""
    with borrowed(model) as data:
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        # the pseudo-inverse: redundant DoFs (two hinges on one axis) make M singular, and MuJoCo accepts them
        compliance = np.diag(np.linalg.pinv(full))
        return 1.0 / np.maximum(compliance, np.finfo(float).tiny)


def smooth_signal(
    gen: np.random.Generator,
    steps: int,
    dt: float,
    channels: int,
    freq_hz: tuple[float, float] = (0.5, 3.0),
    components: int = 3,
) -> np.ndarray:
    """(steps, channels) sums of random sinusoids, each channel of unit peak bound, zero mean-ish."""
    t = np.arange(steps)[:, None] * dt
    out = np.zeros((steps, channels))
    for _ in range(components):
        f = gen.uniform(*freq_hz, size=channels)
        phase = gen.uniform(0, 2 * np.pi, size=channels)
        out += np.sin(2 * np.pi * f * t + phase) / components
    return out


def zero_torque(model: mujoco.MjModel, steps: int) -> np.ndarray:
    return np.zeros((steps, model.nv))


def random_torque(model: mujoco.MjModel, qpos0: np.ndarray, steps: int, seed: int, accel: float) -> np.ndarray:
    """Smooth random torques sized to give about `accel` (rad/s^2 or m/s^2) on each dof."""
    scale = dof_inertia(model, qpos0) * accel * actuated_dofs(model)
    return smooth_signal(rng(seed, "torque"), steps, model.opt.timestep, model.nv) * scale


class PDTracking:
    """PD tracking of a smooth seeded target around qpos0; gains per dof from the joint-space inertia.

    The torque is computed from the state passed in (the MuJoCo reference run); the sequence it
    produced is then replayed on SAPIEN, so both sides receive exactly the same command."""

    def __init__(
        self,
        model: mujoco.MjModel,
        qpos0: np.ndarray,
        steps: int,
        seed: int,
        amplitude: float,
        freq_hz: float,
        damping_ratio: float = 1.0,
    ):
        self.mask = actuated_dofs(model)
        inertia = dof_inertia(model, qpos0)
        omega = 2 * np.pi * freq_hz
        self.kp = inertia * omega**2 * self.mask
        self.kd = inertia * 2 * damping_ratio * omega * self.mask
        self.qadr = np.array([_dof_qposadr(model, d) for d in range(model.nv)])
        lo, hi = _dof_range(model, qpos0)
        pad = np.where(np.isfinite(hi - lo), 0.1 * (hi - lo), 0.0)
        lo, hi = lo + pad, hi - pad
        center = np.clip(qpos0[self.qadr], lo, hi)
        wave = smooth_signal(rng(seed, "pd-target"), steps + 1, model.opt.timestep, model.nv, (0.2, 1.0))
        self.target = np.clip(center + amplitude * wave, lo, hi)

    def __call__(self, step: int, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        q = qpos[self.qadr]
        return np.where(self.mask, self.kp * (self.target[step] - q) - self.kd * qvel, 0.0)


def _dof_qposadr(model: mujoco.MjModel, dof: int) -> int:
    j = model.dof_jntid[dof]
    return model.jnt_qposadr[j] + (dof - model.jnt_dofadr[j])


def _dof_range(model: mujoco.MjModel, qpos0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(model.nv, -np.inf)
    hi = np.full(model.nv, np.inf)
    for j, _, low, high in limited_dofs(model):
        d = model.jnt_dofadr[j]
        lo[d], hi[d] = low, high
    return lo, hi


def hold_ctrl(model: mujoco.MjModel, qpos0: np.ndarray, qvel0: np.ndarray) -> np.ndarray:
    """The ctrl both sides hold at the start: keyframe 0's if the model has a keyframe, else the ctrl under
    which every affine actuator's force is zero at (qpos0, qvel0) (a position servo holds its joint, a motor is
    off); clipped to ctrlrange."""
    if model.nkey:
        ctrl = model.key_ctrl[0].copy()
    else:
        with borrowed(model) as data:
            data.qpos[:], data.qvel[:] = qpos0, qvel0
            mujoco.mj_forward(model, data)
            gain, bias = model.actuator_gainprm[:, 0], model.actuator_biasprm
            affine = model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
            bias_force = np.where(
                affine, bias[:, 0] + bias[:, 1] * data.actuator_length + bias[:, 2] * data.actuator_velocity, 0.0
            )
            ctrl = np.where(gain != 0, -bias_force / np.where(gain != 0, gain, 1.0), 0.0)
    return clip_ctrl(model, ctrl)


def clip_ctrl(model: mujoco.MjModel, ctrl: np.ndarray) -> np.ndarray:
    """ctrl inside each limited actuator's ctrlrange (rows of a sequence too)."""
    lo = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 0], -np.inf)
    hi = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 1], np.inf)
    return np.clip(ctrl, lo, hi)


def ctrl_span(model: mujoco.MjModel) -> np.ndarray:
    """Width of each actuator's ctrlrange (1 for an unlimited ctrl)."""
    return np.where(model.actuator_ctrllimited, np.diff(model.actuator_ctrlrange, axis=1)[:, 0], 1.0)


def ctrl_sequence(
    model: mujoco.MjModel,
    hold: np.ndarray,
    steps: int,
    seed: int,
    step_fraction: float,
    smooth_fraction: float,
    phases: tuple[float, float],
    scale: float = 1.0,
) -> np.ndarray:
    """(steps, nu) seeded ctrl: hold at `hold` for the first phases[0] of the horizon, then a step to a random
    target (hold +- step_fraction of the ctrlrange width), held until phases[1] of the horizon, then smooth random
    motion (smooth_fraction of the width) about that target; `scale` shrinks every deviation from `hold`.
    phases[1] = 1 gives hold-then-step only. Everything stays inside ctrlrange."""
    span = ctrl_span(model)
    target = step_fraction * span * rng(seed, "ctrl-step").uniform(-1.0, 1.0, model.nu)
    out = np.zeros((steps, model.nu))
    first, second = round(phases[0] * steps), round(phases[1] * steps)
    out[first:] = target
    if second < steps:
        wave = smooth_signal(rng(seed, "ctrl-smooth"), steps - second, model.opt.timestep, model.nu, (0.2, 1.0))
        out[second:] += smooth_fraction * span * wave
    return clip_ctrl(model, hold + scale * out)
