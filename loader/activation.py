"""Actuator activation dynamics: MuJoCo's `filter`, `filterexact` and `integrator` actuators, stepped as MuJoCo
steps them.

An actuator with dynamics scales its gain by its activation `act` instead of `ctrl`. The activation obeys an ODE in
ctrl alone, act_dot = (ctrl - act) / tau (filter, filterexact) or ctrl (integrator), which MuJoCo advances after the
step: act += dt act_dot (filterexact: the exact exponential, act += (ctrl - act)(1 - exp(-dt / tau))), clamped to
`actrange` where `actlimited`. The force of a step uses the activation before it (`actearly`: after it). Nothing
here depends on the physics state, so `Activation` reproduces MuJoCo's act exactly and `set_ctrl` feeds it to the
actuator's force law; PhysX itself has no activation. Muscles (whose force also depends on the activation
nonlinearly) and user dynamics are not mapped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

DYN = mujoco.mjtDyn
MAPPED = {int(DYN.mjDYN_FILTER): "filter", int(DYN.mjDYN_FILTEREXACT): "filterexact",
          int(DYN.mjDYN_INTEGRATOR): "integrator"}
MINIMUM_TIME_CONSTANT = 1e-15  # MuJoCo's mjMINVAL, below which tau is not divided by


@dataclass
class Activation:
    """The activation state (MuJoCo's `data.act`, size `model.na`) of a loaded model's actuators."""

    model: mujoco.MjModel
    act: np.ndarray = field(default=None)

    def __post_init__(self):
        if self.act is None:
            self.act = np.zeros(self.model.na)
        m = self.model
        self.actuators = [a for a in range(m.nu) if int(m.actuator_dyntype[a]) in MAPPED]

    def reset(self, act: np.ndarray | None = None) -> None:
        self.act = np.zeros(self.model.na) if act is None else np.asarray(act, dtype=np.float64).copy()

    def _rate(self, a: int, ctrl: float, act: float) -> float:
        if int(self.model.actuator_dyntype[a]) == int(DYN.mjDYN_INTEGRATOR):
            return ctrl
        tau = max(float(self.model.actuator_dynprm[a][0]), MINIMUM_TIME_CONSTANT)
        return (ctrl - act) / tau

    def _next(self, a: int, ctrl: float, act: float) -> float:
        m = self.model
        rate = self._rate(a, ctrl, act)
        timestep = float(m.opt.timestep)
        tau = float(m.actuator_dynprm[a][0])
        if int(m.actuator_dyntype[a]) == int(DYN.mjDYN_FILTEREXACT) and tau >= MINIMUM_TIME_CONSTANT:
            act = act + rate * tau * (1.0 - np.exp(-timestep / tau))
        else:
            act = act + timestep * rate
        if m.actuator_actlimited[a]:
            act = min(max(act, float(m.actuator_actrange[a][0])), float(m.actuator_actrange[a][1]))
        return float(act)

    def inputs(self, ctrl: np.ndarray) -> np.ndarray:
        """What each actuator's gain multiplies this step: ctrl, or the activation (the next one with actearly)."""
        out = np.asarray(ctrl, dtype=np.float64).copy()
        m = self.model
        for a in self.actuators:
            adr = int(m.actuator_actadr[a])
            out[a] = self._next(a, ctrl[a], self.act[adr]) if m.actuator_actearly[a] else self.act[adr]
        return out

    def advance(self, ctrl: np.ndarray) -> None:
        """One step of the activation under this (clamped) ctrl, as MuJoCo takes it after the step."""
        for a in self.actuators:
            adr = int(self.model.actuator_actadr[a])
            self.act[adr] = self._next(a, ctrl[a], self.act[adr])
