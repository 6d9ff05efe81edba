"""The ctrl stage of every step: MuJoCo's `ctrl` clamped to `ctrlrange` (unless `<flag clampctrl="disable"/>`),
and what each actuator's gain multiplies: ctrl, or the activation of MuJoCo's `filter`, `filterexact`,
`integrator` and `muscle` actuators, stepped as MuJoCo steps them (the ODE depends on ctrl and the activation
alone, so the activation is MuJoCo's exactly; a muscle's rate is MuJoCo's own `mju_muscleDynamics`). User dynamics
are not mapped. Derivation: docs/mapping.md#activation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..model.actuators import DYN, MAPPED_DYNAMICS
from ..model.mj import MJMINVAL
from ..model.options import Options


@dataclass
class Activation:
    """The activation state (MuJoCo's `data.act`, size `model.na`) of a loaded model's actuators."""

    model: mujoco.MjModel
    act: np.ndarray = field(default=None)
    timestep: float | None = None  # one PhysX step (the scene's); None: the model's

    def __post_init__(self):
        m = self.model
        self.timestep = float(m.opt.timestep if self.timestep is None else self.timestep)
        if self.act is None:
            self.act = np.zeros(m.na)
        self.actuators = np.array([a for a in range(m.nu) if int(m.actuator_dyntype[a]) in MAPPED_DYNAMICS], dtype=int)
        a = self.actuators
        self.adr = m.actuator_actadr[a].astype(int)
        self.integrator = m.actuator_dyntype[a] == int(DYN.mjDYN_INTEGRATOR)
        self.muscles = np.flatnonzero(m.actuator_dyntype[a] == int(DYN.mjDYN_MUSCLE))  # positions among `actuators`
        self.muscle_prm = [np.array(m.actuator_dynprm[a[i], :3], dtype=np.float64) for i in self.muscles]
        tau = m.actuator_dynprm[a, 0].astype(float)
        self.tau = np.maximum(tau, MJMINVAL)
        self.exact = (m.actuator_dyntype[a] == int(DYN.mjDYN_FILTEREXACT)) & (tau >= MJMINVAL)
        self.decay = 1.0 - np.exp(-self.timestep / self.tau)  # filterexact's share of the gap closed in a step
        self.early = m.actuator_actearly[a].astype(bool)
        self.any_early = bool(self.early.any())
        self.limited = m.actuator_actlimited[a].astype(bool)
        self.low = np.where(self.limited, m.actuator_actrange[a, 0], -np.inf)
        self.high = np.where(self.limited, m.actuator_actrange[a, 1], np.inf)
        # the kinds present: a step leaves out the arithmetic of those absent (the same numbers, fewer array calls)
        self.any_integrator, self.any_exact = bool(self.integrator.any()), bool(self.exact.any())
        self.any_limited = bool(self.limited.any())

    def reset(self, act: np.ndarray | None = None) -> None:
        self.act = np.zeros(self.model.na) if act is None else np.asarray(act, dtype=np.float64).copy()

    def _next(self, ctrl: np.ndarray) -> np.ndarray:
        """Every mapped actuator's activation after one step under `ctrl` (MuJoCo's mj_advance)."""
        act = self.act[self.adr]
        u = np.asarray(ctrl, dtype=np.float64)[self.actuators]
        rate = (u - act) / self.tau
        if self.any_integrator:
            rate = np.where(self.integrator, u, rate)
        for i, prm in zip(self.muscles.tolist(), self.muscle_prm):
            rate[i] = mujoco.mju_muscleDynamics(float(u[i]), float(act[i]), prm)
        step = self.timestep * rate
        if self.any_exact:
            step = np.where(self.exact, rate * self.tau * self.decay, step)
        return np.clip(act + step, self.low, self.high) if self.any_limited else act + step

    def inputs(self, ctrl: np.ndarray) -> np.ndarray:
        """What each actuator's gain multiplies this step: ctrl, or the activation (the next one with actearly)."""
        out = np.asarray(ctrl, dtype=np.float64).copy()
        if self.actuators.size:
            act = self.act[self.adr]
            out[self.actuators] = np.where(self.early, self._next(ctrl), act) if self.any_early else act
        return out

    def advance(self, ctrl: np.ndarray) -> None:
        """One step of the activation under this (clamped) ctrl, as MuJoCo takes it after the step."""
        if self.actuators.size:
            self.act[self.adr] = self._next(ctrl)


class Command:
    """The clamp bounds (-inf..inf where an actuator is not ctrllimited) and the clamp flag, planned once."""

    def __init__(self, model: mujoco.MjModel, options: Options, activation: Activation | None):
        self.nu, self.activation = model.nu, activation
        limited = model.actuator_ctrllimited.astype(bool)
        self.low = np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf)
        self.high = np.where(limited, model.actuator_ctrlrange[:, 1], np.inf)
        self.clamps = bool(limited.any()) and options.clamps_ctrl

    def __call__(self, ctrl, actuated: bool, advance: bool):
        """(clamped ctrl, what the gains multiply, the activation at the step's start or None); `advance` takes
        the activation one step further (only while the actuators are on)."""
        ctrl = np.zeros(self.nu) if ctrl is None else np.asarray(ctrl, dtype=np.float64)
        ctrl = np.minimum(np.maximum(ctrl, self.low), self.high) if self.clamps else ctrl.copy()
        if self.activation is None or not actuated:
            return ctrl, ctrl, None
        act = self.activation.act.copy()
        inputs = self.activation.inputs(ctrl)
        if advance:
            self.activation.advance(ctrl)
        return ctrl, inputs, act
