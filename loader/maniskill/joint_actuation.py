"""The `mujoco_ctrl_tensor` control mode: MuJoCo's `ctrl` through the joint actuation law
(`loader/plan/joint_actuation.py`) written over (env, DoF) tensors, read from and written to ManiSkill's state
tensors before every physics step, with no MuJoCo call and no per-env or per-DoF Python loop. The same torch code
runs on the CPU backend (one env) and on the GPU backend (every sub-scene at once, the state fetched and `qf`
applied on the device); the CPU tests exercise it, and no GPU has run it yet. Its drives match MuJoCo's implicit
damping under PGS only: under TGS the mode warns (tests/test_maniskill_joint_actuation.py)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import torch
from gymnasium import spaces
from mani_skill.agents.controllers.base_controller import BaseController, ControllerConfig
from mani_skill.utils import common

from ..errors import SceneMismatchWarning
from ..plan.joint_actuation import FILTEREXACT, INTEGRATOR, NO_DYNAMICS, JointActuation
from ..plan.physx_settings import uses_tgs
from ..servos import UNLIMITED

# the law's arithmetic: its terms (kp q, kp ctrl, the drives' kv v) are large and their sum small, which float32
# would round a thousand times coarser than PhysX's float32 qf rounds the sum
LAW_DTYPE = torch.float64
TGS_NOTE = (
    "mujoco_ctrl_tensor: the drives hold MuJoCo's implicit damping under PGS; TGS damps a drive over its position "
    "iterations and moves the joints elsewhere: set sim_config's scene_config enable_tgs=False"
)


class Law:
    """The plan's arrays as tensors on one device and dtype."""

    def __init__(self, plan: JointActuation, timestep: float, device, dtype=torch.float32):
        def tensor(array):
            return torch.as_tensor(np.asarray(array, np.float64), dtype=dtype, device=device)

        self.moment, self.gain = tensor(plan.moment), tensor(plan.gain)
        self.bias0, self.bias1, self.bias2 = (tensor(row) for row in plan.bias)
        self.ctrl_low, self.ctrl_high = tensor(plan.ctrl_range[0]), tensor(plan.ctrl_range[1])
        self.force_low, self.force_high = tensor(plan.force_range[0]), tensor(plan.force_range[1])
        self.joint_low, self.joint_high = tensor(plan.joint_range[0]), tensor(plan.joint_range[1])
        self.stiffness, self.spring_ref = tensor(plan.stiffness), tensor(plan.spring_ref)
        self.held_damping = tensor(plan.held_damping())
        self.drive_damping, self.explicit_damping = tensor(plan.drive_damping), tensor(plan.explicit_damping)
        self.held_gain, self.moment_squared = tensor(plan.held * -plan.bias[2]), tensor(plan.moment**2)
        dynamics = plan.dynamics
        self.activated = torch.as_tensor(dynamics != NO_DYNAMICS, device=device)
        self.any_activated = bool(np.any(dynamics != NO_DYNAMICS))  # read on the host, never synced from a device
        self.integrates = torch.as_tensor(dynamics == INTEGRATOR, device=device)
        self.exact = torch.as_tensor(dynamics == FILTEREXACT, device=device)
        self.early = torch.as_tensor(plan.act_early, device=device)
        self.time_constant = tensor(plan.time_constant)
        self.act_low, self.act_high = tensor(plan.act_range[0]), tensor(plan.act_range[1])
        self.timestep = float(timestep)
        self.exact_step = tensor(
            plan.time_constant * -np.expm1(-self.timestep / plan.time_constant)
        )  # tau (1 - e^-dt/tau)


def next_activation(law: Law, ctrl: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
    """MuJoCo's activation one step on (`mj_nextActivation`) from `act` (env, nu) under `ctrl`: an integrator's rate
    is the clamped ctrl, a filter's (ctrl - act) / tau, stepped by Euler or, for filterexact, exactly; then held to
    actrange. An actuator without dynamics keeps its column."""
    ctrl = torch.clamp(ctrl, law.ctrl_low, law.ctrl_high)
    rate = torch.where(law.integrates, ctrl, (ctrl - act) / law.time_constant)
    stepped = act + rate * torch.where(law.exact, law.exact_step, torch.full_like(law.exact_step, law.timestep))
    return torch.where(law.activated, torch.clamp(stepped, law.act_low, law.act_high), act)


def joint_forces(
    law: Law,
    ctrl: torch.Tensor,
    q: torch.Tensor,
    v: torch.Tensor,
    target: torch.Tensor | None = None,
    act: torch.Tensor | None = None,
) -> torch.Tensor:
    """The joint forces (env, DoF) the law writes as `qf` for `ctrl` (env, nu) at the state (q, v) (env, DoF), with
    the drives aimed at the velocity `target` (None: v). MuJoCo's force at the step's start (the actuators', each
    joint's sum within its range; the springs, the dampers it applies explicitly), less what the drives give: they
    hold D (v1 - target) where MuJoCo's step holds -D v1 (its dampers, and the kv of each actuator whose clamp does
    not bind), so the law adds D target back and puts each held kv's start term kv v in its place. A binding clamp's
    kv has no implicit term in MuJoCo; its drive share is left aimed at `target`, so the nearer the target to the
    end velocity, the less it pulls: the controller aims at the velocity extrapolated from the last step, which also
    keeps every drive's pull small, whatever the solver. An actuator with dynamics multiplies its activation (`act`,
    env x nu; None: zeros), or its next one where it acts early."""
    inputs = torch.clamp(ctrl, law.ctrl_low, law.ctrl_high)
    if law.any_activated:
        act = torch.zeros_like(inputs) if act is None else act
        act = torch.where(law.early, next_activation(law, ctrl, act), act)
        inputs = torch.where(law.activated, act, inputs)
    length, rate = q @ law.moment.T, v @ law.moment.T
    raw = law.gain * inputs + law.bias0 + law.bias1 * length + law.bias2 * rate
    force = torch.clamp(raw, law.force_low, law.force_high)
    summed = force @ law.moment
    actuated = torch.clamp(summed, law.joint_low, law.joint_high)
    bound = ((force != raw).to(v.dtype) * law.held_gain) @ law.moment_squared  # per DoF, the clamped actuators' kv
    bound = torch.where(actuated != summed, law.held_damping, bound)  # a joint's actuatorfrcrange: all of it
    target = v if target is None else target
    held = law.held_damping - bound
    qf = actuated + law.stiffness * (law.spring_ref - q) - law.explicit_damping * v + held * v
    return qf - (law.drive_damping - bound) * target


class JointActuationController(BaseController):
    """Holds the last action as ctrl (env, nu); before every physics step, the law's `qf` for the robot's state."""

    config: JointActuationConfig
    sets_target_qpos = False
    sets_target_qvel = False

    def _initialize_action_space(self):
        low, high = np.float32(self.config.low), np.float32(self.config.high)
        self.single_action_space = spaces.Box(low, high, dtype=np.float32)
        self.law = Law(self.config.plan, float(self.scene.timestep), self.device, LAW_DTYPE)
        self.ctrl = torch.zeros((self.scene.num_envs, len(self.config.low)), device=self.device, dtype=LAW_DTYPE)
        self.previous: torch.Tensor | None = None  # the velocities at the last physics step's start
        self.fresh: torch.Tensor | None = None  # the envs reset since the last step, where only some were (`reset`)
        self.resetting: torch.Tensor | None = None  # the envs the agent's reset marked (`MJCFAgent.reset`)
        self.act = torch.zeros_like(self.ctrl)  # the actuators' activations (MuJoCo's act), per env
        self.physx_joints: list | None = None  # on the CPU backend, the sub-scene's PhysX joints (`aim`)

    def set_drive_property(self):
        """The drives hold the implicit damping alone (no stiffness; a velocity target each step); gravity on, as in
        MuJoCo, but on the links of fully compensated bodies. The mode starts afresh: no last step, activations at
        zero."""
        self.previous, self.fresh, self.act = None, None, torch.zeros_like(self.act)
        if uses_tgs(self.scene.sub_scenes[0]):
            warnings.warn(TGS_NOTE, SceneMismatchWarning, stacklevel=2)
        weightless = set(self.config.plan.weightless)
        for index, link in enumerate(self.articulation.links):
            link.disable_gravity = index in weightless
        indices = self.active_joint_indices.cpu().numpy()
        for joint, damping in zip(self.joints, self.config.plan.drive_damping[indices].tolist()):
            joint.set_drive_properties(0.0, damping, force_limit=UNLIMITED, mode="force")

    def reset(self):
        """The envs an `env.reset` resets start as MuJoCo's reset starts them: ctrl and activations zero, and no last
        step to extrapolate the drives' aim from. ManiSkill marks those envs while it resets the agent and not while
        it resets the controllers, so the agent hands the mark on (`resetting`); without one, every env resets. The
        others run on untouched (tests/test_maniskill_joint_actuation.py::test_a_partial_reset_restarts_only_its_envs).
        """
        envs, self.resetting = self.resetting, None
        if envs is None or bool(envs.all()):
            self.ctrl, self.act = torch.zeros_like(self.ctrl), torch.zeros_like(self.act)
            self.previous = self.fresh = None
            return
        envs = envs.to(self.device)
        if not bool(envs.any()):
            return
        self.ctrl[envs], self.act[envs] = 0.0, 0.0
        if self.previous is not None:
            self.fresh = envs if self.fresh is None else self.fresh | envs

    def set_action(self, action):
        self.ctrl = common.to_tensor(self._preprocess_action(action), device=self.device).to(LAW_DTYPE)

    def end_velocity(self, v: torch.Tensor) -> torch.Tensor:
        """The step's end velocity as the last step's change carries on from `v` (`v` itself in an env reset since
        the last step)."""
        if self.previous is None:
            return v
        if self.fresh is not None:
            self.previous, self.fresh = torch.where(self.fresh[:, None], v, self.previous), None
        return 2.0 * v - self.previous

    def aim(self, target: torch.Tensor) -> None:
        """Every drive's velocity target (env, DoF): one tensor write on the device; on the CPU backend, the one
        sub-scene's PhysX joints directly (ManiSkill's setter converts each joint's target on its own)."""
        if self.config.results:
            if self.physx_joints is None:  # the property builds a new list per call
                self.physx_joints = self.config.results[0].articulations[0].active_joints
            for joint, velocity in zip(self.physx_joints, target[0].tolist()):
                joint.set_drive_velocity_target(velocity)
            return
        indices = self.active_joint_indices
        self.articulation.set_joint_drive_velocity_targets(target[:, indices].float(), self.joints, indices)

    def before_simulation_step(self):
        """The state in, the drives' velocity targets (the end velocity extrapolated from the last step) and the
        law's `qf` out; the activations one step on."""
        px = self.scene.px
        if self.scene.gpu_sim_enabled:  # the state of the last physics step, on the device
            px.gpu_fetch_articulation_qpos()
            px.gpu_fetch_articulation_qvel()
        q, v = self.articulation.get_qpos().to(LAW_DTYPE), self.articulation.get_qvel().to(LAW_DTYPE)
        target = self.end_velocity(v)
        self.aim(target)
        self.articulation.set_qf(joint_forces(self.law, self.ctrl, q, v, target, self.act).float())
        self.previous = v
        self.act = next_activation(self.law, self.ctrl, self.act)
        if self.scene.gpu_sim_enabled:
            px.gpu_apply_articulation_target_velocity()
            px.gpu_apply_articulation_qf()


@dataclass
class JointActuationConfig(ControllerConfig):
    low: list[float] = field(default_factory=list)  # ctrlrange (or -inf) per actuator
    high: list[float] = field(default_factory=list)
    plan: JointActuation | None = None
    results: list = field(default_factory=list)  # the CPU backend's one LoadResult (its PhysX joints); none on GPU
    normalize_action: bool = False
    controller_cls = JointActuationController
