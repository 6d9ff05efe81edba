"""The `mujoco_ctrl` control mode: the action is MuJoCo's `ctrl` vector, applied before every physics step exactly as
`LoadResult.set_ctrl` applies it (its joint forces from MuJoCo's own step where the model allows:
`Controller.use_mujoco_step`), so a MuJoCo policy drives the robot unchanged (CPU only: the per-step terms read
the state on the host). Gravity stays on, as in MuJoCo
(tests/test_maniskill.py::test_mujoco_ctrl_follows_mujoco_stepping_the_same_ctrl)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from gymnasium import spaces
from mani_skill.agents.controllers.base_controller import BaseController, ControllerConfig
from mani_skill.utils import common

from ..errors import command_vector


class MujocoCtrlController(BaseController):
    """Holds the last action as `ctrl`; `set_ctrl` on each sub-scene's `LoadResult` before every physics step."""

    config: MujocoCtrlConfig
    sets_target_qpos = False
    sets_target_qvel = False

    def _initialize_action_space(self):
        self.single_action_space = spaces.Box(
            np.float32(self.config.low), np.float32(self.config.high), dtype=np.float32
        )
        self.ctrl = np.zeros(len(self.config.low))

    def set_drive_property(self):
        for link in self.articulation.links:
            link.disable_gravity = False
        for result in self.config.results:
            result.release()  # forget drive writes made by another mode, then own the drives again
            result.controller.use_mujoco_step(self.config.mujoco_step)
            result.set_ctrl(self.ctrl, advance=False)

    def reset(self):
        self.ctrl = np.zeros(len(self.config.low))
        for result in self.config.results:
            result.set_act(None)

    def set_action(self, action):
        """The action as MuJoCo's ctrl, checked once here (`ControlError` for a non-finite entry) rather than in
        each of the physics steps it is held over."""
        action = common.to_numpy(self._preprocess_action(action))
        ctrl = np.asarray(action, np.float64).reshape(-1, len(self.config.low))[0]
        result = self.config.results[0]
        self.ctrl = command_vector(result.path, "ctrl", ctrl, len(self.config.low), "actuators (nu)")

    def before_simulation_step(self):
        for result in self.config.results:
            result.controller.set_ctrl(self.ctrl)


@dataclass
class MujocoCtrlConfig(ControllerConfig):
    low: list[float] = field(default_factory=list)  # ctrlrange (or -inf) per actuator
    high: list[float] = field(default_factory=list)
    results: list = field(default_factory=list)  # one LoadResult per sub-scene
    # the joint forces from MuJoCo's own step where the model allows (`Controller.use_mujoco_step`), else the terms
    mujoco_step: bool = True
    normalize_action: bool = False
    controller_cls = MujocoCtrlController
