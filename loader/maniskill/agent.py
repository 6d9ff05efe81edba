"""ManiSkill robots from MJCF files: `register_agent(mjcf_path, uid)` registers a `BaseAgent` subclass whose robot is
built by this package's loader, whose keyframes are the file's `<key>`s and whose control modes come from its actuators
(`loader/servos.py`): `pd_joint_pos` and `pd_joint_delta_pos` from position servos, `pd_joint_vel` from velocity servos,
`mujoco_ctrl` (CPU) for MuJoCo's ctrl vector through `set_ctrl`, and `mujoco_ctrl_tensor` (CPU and GPU) for it
through the joint actuation law on ManiSkill's tensors. Docs: docs/maniskill.md."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np
from mani_skill.agents import registration
from mani_skill.agents.base_agent import BaseAgent, Keyframe
from mani_skill.agents.controllers.pd_joint_pos import (
    PDJointPosControllerConfig,
    PDJointPosMimicControllerConfig,
)
from mani_skill.agents.controllers.pd_joint_vel import PDJointVelControllerConfig
from mani_skill.utils.structs.pose import Pose

from ..errors import UnsupportedFeatureWarning
from ..mjcf_loader import MJCFLoader as CoreLoader
from ..plan.joint_actuation import JointActuation, plan_joint_actuation, robot_articulation, robot_indices
from ..plan.rigid_tree import RigidTree, rigid_tree
from ..servos import Motor, Servo, derive, motors
from .joint_actuation import JointActuationConfig, JointActuationController
from .mujoco_ctrl import MujocoCtrlConfig
from .scene_loader import MJCFLoader

UNREACHED = 1e4  # rad or m: the PhysX limits of a joint whose limits `mujoco_ctrl_tensor`'s law carries
TENSOR = "mujoco_ctrl_tensor"
LAWS = ("mujoco_ctrl", TENSOR)  # the modes whose joint forces this loader writes, where ManiSkill's drives write none
DELTA = 0.1  # pd_joint_delta_pos: ManiSkill's usual bound on a step's change of target (rad or m)


class MJCFAgent(BaseAgent):
    """A robot from an MJCF file (set up by `register_agent`). `results`: one `LoadResult` per sub-scene (CPU)."""

    servos: ClassVar[list[Servo]] = []
    motors: ClassVar[list[Motor]] = []
    ctrl_low: ClassVar[list[float]] = []
    ctrl_high: ClassVar[list[float]] = []
    # `mujoco_ctrl_tensor`'s law, or why the model's actuators are outside it
    joint_actuation: ClassVar[JointActuation | str] = "not planned"
    rigid_tree: ClassVar[RigidTree | None] = None  # the robot's tree as built, for the law's M and c
    # the joints whose limits the law carries as MuJoCo's soft rows: built free of PhysX's hard limits in an env made
    # in `mujoco_ctrl_tensor`
    law_limited: ClassVar[list[str]] = []
    law_limited_dofs: ClassVar[list[int]] = []  # their DoFs
    # the connects and welds (MuJoCo's ids) the law carries as MuJoCo's soft rows: their D6 joints free in
    # `mujoco_ctrl_tensor`
    law_loops: ClassVar[list[int]] = []
    robot_index: ClassVar[int] = 0  # the model's articulation that is the robot (`robot_articulation`)

    def __init__(self, scene, control_freq: int, control_mode: str | None = None, *args, **kwargs):
        self.built_mode = control_mode  # the env's control mode, which decides the build (`_load_articulation`)
        self.gravity: dict[str, list[bool]] = {}  # per mode made, its links' disable_gravity (`set_control_mode`)
        super().__init__(scene, control_freq, control_mode, *args, **kwargs)

    def _load_articulation(self, initial_pose=None):
        """The env's `initial_pose` places the file's world frame; the robot's root keeps its pose in it."""
        if self.build_separate:
            raise NotImplementedError("build_separate: MJCF agents build in every sub-scene at once")
        loader = MJCFLoader()
        loader.set_scene(self.scene)
        loader.name = self.uid if self._agent_idx is None else f"{self.uid}-agent-{self._agent_idx}"
        loader.fix_root_link = self.fix_root_link
        loader.disable_self_collisions = self.disable_self_collisions
        loader.standing_by = set(self.law_loops) if self.built_mode == TENSOR else set()
        builder = loader.parse(self.mjcf_path)["articulation_builders"][self.robot_index]
        # the law's soft limit rows, not PhysX's hard limits (a band no joint reaches: PhysX keeps a joint built
        # limited so, while the loader's own reset holds its limits wide of MuJoCo's range)
        if self.built_mode == TENSOR:
            for link in builder.link_builders:
                if link.joint_record.name in self.law_limited:
                    link.joint_record.limits = [[-UNREACHED, UNREACHED]]
        if initial_pose is None:
            builder.initial_pose = Pose.create(builder.initial_pose)
        else:  # on the device of the env's pose (a batched pose may live on the GPU)
            placed = Pose.create(initial_pose)
            builder.initial_pose = placed * Pose.create(builder.initial_pose, device=placed.device)
        self.robot = builder.build()
        self.robot_link_names = [link.name for link in self.robot.get_links()]
        self.results = loader.results
        for result in self.results:
            result.release()  # PD modes drive the joints; mujoco_ctrl takes them back

    def set_control_mode(self, control_mode: str | None = None):
        """ManiSkill's switch of control mode, made whole on the CPU backend. ManiSkill sets a mode's drives (and
        gravity) only when it first makes its controller, so a switch back kept the last mode's; and this loader's
        modes own more of the joints than drives. So leaving one of them hands the joints back (`release()`: MuJoCo's
        range as PhysX's hard limits, no `qf`), a mode made before sets its drives and its links' gravity again, and
        `mujoco_ctrl_tensor` moves PhysX's limits out of its soft rows' way. On the GPU, PhysX keeps what the env
        was built with: a switch that needs other limits is warned
        (tests/test_maniskill.py::test_a_switch_of_control_mode_sets_the_modes_drives_and_limits)."""
        leaving = getattr(self, "_control_mode", None)
        mode = self._default_control_mode if control_mode is None else control_mode
        made, gpu = mode in self.controllers, self.scene.gpu_sim_enabled
        if leaving in LAWS and mode != leaving and mode in self.supported_control_modes and not gpu:
            for result in self.results:
                result.release()
        super().set_control_mode(control_mode)
        if not made:
            self.gravity[mode] = [bool(link.disable_gravity.all()) for link in self.robot.links]
        elif mode != leaving and not gpu:
            self._resume(mode)
        if self.law_limited_dofs and mode != leaving:
            self._limits_for(mode, gpu)
        if self.law_loops and mode != leaving:
            self._loops_for(mode, gpu)

    def _resume(self, mode: str) -> None:
        """A mode made before, switched to again: its links' gravity as it made them, and its drives."""
        for link, weightless in zip(self.robot.links, self.gravity[mode]):
            link.disable_gravity = weightless
        self.controller.set_drive_property()

    def _limits_for(self, mode: str, gpu: bool) -> None:
        """PhysX's limits of the joints whose limits the law carries, as `mode` needs them: out of the way under
        `mujoco_ctrl_tensor`, MuJoCo's range (as `release()` left them) under the others."""
        if gpu:
            self._kept_as_built(mode, "joint limits")
            return
        for result in self.results if mode == TENSOR else ():
            joints = result.articulations[0].get_active_joints()
            for dof in self.law_limited_dofs:
                joints[dof].set_limit(np.array([[-UNREACHED, UNREACHED]], np.float32))

    def _loops_for(self, mode: str, gpu: bool) -> None:
        """The D6 joints of the connects and welds the law carries, as `mode` needs them: free under
        `mujoco_ctrl_tensor`, whose rows hold the loops; locked under the others (as `release()`, which leaving the
        mode calls, locks them)."""
        if gpu:
            self._kept_as_built(mode, "loops' D6 joints")
            return
        for result in self.results if mode == TENSOR else ():
            for law in filter(None, map(result.controller.soft_joint, self.law_loops)):  # a site's has no D6
                law.stand_by()

    def _kept_as_built(self, mode: str, what: str) -> None:
        """On the GPU, PhysX keeps what the env was built with: a switch into or out of `mujoco_ctrl_tensor` that
        needs other settings is warned."""
        if (mode == TENSOR) != (self.built_mode == TENSOR):
            warnings.warn(
                f"{self.uid}: on physx_cuda PhysX keeps the {what} the env was built with "
                f"({self._default_control_mode}), which {mode} does not want; make the env with "
                f"control_mode={mode!r}",
                UnsupportedFeatureWarning,
                stacklevel=4,
            )

    def reset(self, init_qpos=None):
        """ManiSkill's reset, and the envs it resets handed to `mujoco_ctrl_tensor`'s controller: ManiSkill marks them
        (its scene's `_reset_mask`, which its own PD controllers read) only while it resets the agent."""
        super().reset(init_qpos)
        mask = getattr(self.scene, "_reset_mask", None)
        if mask is None:
            return
        active = self.controllers.get(self._control_mode)
        for controller in getattr(active, "controllers", {}).values():
            if isinstance(controller, JointActuationController):
                controller.resetting = mask.clone()

    @property
    def _controller_configs(self):
        joints = [joint.name for joint in self.robot.active_joints]
        positions = [s for s in self.servos if s.kind == "position"]
        velocities = [s for s in self.servos if s.kind == "velocity"]
        if positions:
            timestep = float(self.scene.timestep)
            configs = {
                "pd_joint_pos": _pd_joint_pos(positions, timestep, delta=False),
                "pd_joint_delta_pos": _pd_joint_pos(positions, timestep, delta=True),
            }
        else:  # ManiSkill's default PD gains on the joints the motors drive (all joints without motors)
            configs = dict(super()._controller_configs)
            driven = {m.joint: m.force_limit for m in self.motors}
            for config in configs.values() if driven else []:
                config.joint_names, config.force_limit = list(driven), list(driven.values())
        if velocities:
            configs["pd_joint_vel"] = {
                "balance_passive_force": False,
                **{
                    s.actuator: PDJointVelControllerConfig(
                        s.joints, s.lower, s.upper, s.damping, s.force_limit, normalize_action=s.lower is not None
                    )
                    for s in velocities
                },
            }
        if self.results and self.ctrl_low:  # a model with actuators, on the CPU, of one tree (its `LoadResult`)
            configs["mujoco_ctrl"] = {
                "balance_passive_force": False,
                "ctrl": MujocoCtrlConfig(joints, list(self.ctrl_low), list(self.ctrl_high), self.results),
            }
        if isinstance(self.joint_actuation, JointActuation) and self.ctrl_low:
            configs[TENSOR] = {
                "balance_passive_force": False,
                "ctrl": JointActuationConfig(
                    joints,
                    list(self.ctrl_low),
                    list(self.ctrl_high),
                    self.joint_actuation,
                    self.rigid_tree,
                    self.results,
                ),
            }
        return configs


def _pd_joint_pos(servos: list[Servo], timestep: float, delta: bool) -> dict:
    """One controller for the single-joint servos, one mimic controller per coupled servo; gravity on, as the
    servos hold against it in MuJoCo; damping less K dt (`Servo.physx_damping`). Delta mode moves the target
    (`use_target`), so zero actions hold it."""
    bounds = (
        {"lower": -DELTA, "upper": DELTA, "normalize_action": True, "use_delta": True, "use_target": True}
        if delta
        else {}
    )
    single = [s for s in servos if not s.mimic]
    configs: dict = {"balance_passive_force": False}
    if single:
        configs["arm"] = PDJointPosControllerConfig(
            [s.joints[0] for s in single],
            stiffness=[s.stiffness[0] for s in single],
            damping=[s.physx_damping(timestep)[0] for s in single],
            force_limit=[s.force_limit[0] for s in single],
            **(
                bounds
                or {"lower": [s.lower for s in single], "upper": [s.upper for s in single], "normalize_action": False}
            ),
        )
        if not delta and any(s.lower is None for s in single):
            configs["arm"].lower = configs["arm"].upper = None  # the joints' limits
    for s in (s for s in servos if s.mimic):
        configs[s.actuator] = PDJointPosMimicControllerConfig(
            s.joints,
            stiffness=s.stiffness,
            damping=s.physx_damping(timestep),
            force_limit=s.force_limit,
            mimic=s.mimic,
            **(bounds or {"lower": s.lower, "upper": s.upper, "normalize_action": False}),
        )
    return configs


def register_agent(
    mjcf_path: str | Path | mujoco.MjSpec,
    uid: str,
    fix_root_link: bool = True,
    disable_self_collisions: bool = False,
    override: bool = False,
) -> type[MJCFAgent]:
    """Register the robot of `mjcf_path` with ManiSkill as `uid` (then `gym.make(..., robot_uids=uid)`). The file
    is loaded once here, in a scene of its own, for its keyframes and servos. An `MjSpec` (built or edited in Python)
    is compiled as it is, here and at every build of the robot."""
    path = mjcf_path if isinstance(mjcf_path, mujoco.MjSpec) else str(Path(mjcf_path).resolve())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the env's load warns its notes
        reference = CoreLoader().load(path)
    model, robot = reference.model, robot_articulation(reference.model, reference.mapping)
    articulation = reference.articulations[robot]
    keyframes = {}
    for k in range(model.nkey):
        reference.reset(k)
        keyframes[model.key(k).name or f"key{k}"] = Keyframe(
            pose=articulation.get_root_pose(),
            qpos=np.asarray(articulation.get_qpos()),
            qvel=np.asarray(articulation.get_qvel()),
        )
    limited = model.actuator_ctrllimited.astype(bool)
    dof_of_joint, link_of_body = robot_indices(reference.mapping, robot)
    driven = {joint.name for joint in articulation.get_active_joints()}  # the other trees' actuators drive no drive
    attributes = {
        "uid": uid,
        "mjcf_path": path,
        "fix_root_link": fix_root_link,
        "disable_self_collisions": disable_self_collisions,
        "keyframes": keyframes,
        "robot_index": robot,
        "servos": [servo for servo in derive(reference) if set(servo.joints) <= driven],
        "motors": [motor for motor in motors(reference) if motor.joint in driven],
        "ctrl_low": np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf).tolist(),
        "ctrl_high": np.where(limited, model.actuator_ctrlrange[:, 1], np.inf).tolist(),
    }
    try:  # the law's M and c need the tree; a joint it does not take keeps the robot out of the mode, saying why
        attributes["rigid_tree"] = rigid_tree(articulation)
        attributes["joint_actuation"] = plan = plan_joint_actuation(model, dof_of_joint, articulation.dof, link_of_body)
        if isinstance(plan, JointActuation):
            joints, limited = articulation.get_active_joints(), np.flatnonzero(plan.limits.limited).tolist()
            attributes["law_limited"], attributes["law_limited_dofs"] = [joints[dof].name for dof in limited], limited
            attributes["law_loops"] = list(plan.connects.equalities) + list(plan.welds.equalities)
    except ValueError as error:
        attributes["joint_actuation"] = str(error)
    agent = type(f"MJCFAgent_{uid}", (MJCFAgent,), attributes)
    return registration.register_agent(override=override)(agent)
