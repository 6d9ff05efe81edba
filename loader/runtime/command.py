"""The ctrl stage of every step: MuJoCo's `ctrl` clamped to `ctrlrange` (unless `<flag clampctrl="disable"/>`),
and what each actuator's gain multiplies (ctrl, or the activation, `activation.py`)."""

from __future__ import annotations

import mujoco
import numpy as np

from .activation import Activation

CLAMPCTRL = int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)


class Command:
    """The clamp bounds (-inf..inf where an actuator is not ctrllimited), planned once; the model's flag is read
    every step."""

    def __init__(self, model: mujoco.MjModel, activation: Activation | None):
        self.model, self.activation = model, activation
        limited = model.actuator_ctrllimited.astype(bool)
        self.low = np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf)
        self.high = np.where(limited, model.actuator_ctrlrange[:, 1], np.inf)
        self.limited = bool(limited.any())

    def __call__(self, ctrl, actuated: bool, advance: bool):
        """(clamped ctrl, what the gains multiply, the activation at the step's start or None); `advance` takes
        the activation one step further (only while the actuators are on)."""
        model = self.model
        ctrl = np.zeros(model.nu) if ctrl is None else np.asarray(ctrl, dtype=np.float64)
        if self.limited and not model.opt.disableflags & CLAMPCTRL:
            ctrl = np.minimum(np.maximum(ctrl, self.low), self.high)
        else:
            ctrl = ctrl.copy()
        if self.activation is None or not actuated:
            return ctrl, ctrl, None
        act = self.activation.act.copy()
        inputs = self.activation.inputs(ctrl)
        if advance:
            self.activation.advance(ctrl)
        return ctrl, inputs, act
