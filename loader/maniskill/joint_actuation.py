"""The `mujoco_ctrl_tensor` control mode: MuJoCo's `ctrl` through the joint actuation law
(`loader/plan/joint_actuation.py`) written over (env, DoF) tensors, read from and written to ManiSkill's state
tensors before every physics step, with no MuJoCo call and no per-env or per-DoF Python loop. The same torch code
runs on the CPU backend (one env) and on the GPU backend (every sub-scene at once, the state fetched and `qf`
applied on the device); the CPU tests exercise it, and no GPU has run it yet.

Each step it solves MuJoCo's step of the joints from the state, with the robot's joint-space inertia M and bias c
computed on the tensors (`inertia.py`), and writes the joint force that takes PhysX's joints to that step's end
velocity v1, `qf = M (v1 - v0) / dt + c`: PhysX steps a joint force explicitly under either solver, so the mode
follows MuJoCo under ManiSkill's default TGS as under PGS. The drives keep the implicit damping's diagonal, aimed at
v1, where they hold nothing if PhysX's M is the law's; where float32 makes them differ (light links under heavy
servos) they hold the joints to v1. A slide on a turning link keeps no drive: PhysX's drive measures its velocity
short of the centripetal term (tests/test_maniskill_joint_actuation.py). A floating root ends each step where MuJoCo's
step leaves it, written before the next, wherever no contact pushed the tree (`free_root.py`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
import torch
from gymnasium import spaces
from mani_skill.agents.controllers.base_controller import BaseController, ControllerConfig
from mani_skill.utils import common
from mani_skill.utils.structs.pose import Pose

from ..plan.joint_actuation import FILTEREXACT, INTEGRATOR, NO_DYNAMICS, JointActuation
from ..plan.rigid_tree import RigidTree, turning_slides
from ..servos import UNLIMITED
from .constraint_rows import ROW_STEPS, Connects, Couplings, RowSet, SpatialRowSet, Welds, constraint_force
from .free_root import RootRows, free_velocity, physx_velocity
from .inertia import Inertia, mass_matrix_and_bias, motion
from .spatial_tendons import SpatialTendonTensors, spatial_tendons

# the law's arithmetic: its terms (kp q, kp ctrl, the drives' kv v) are large and their sum small, which float32
# would round a thousand times coarser than PhysX's float32 qf rounds the sum
LAW_DTYPE = torch.float64


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
        self.damping, self.implicit_damping = tensor(plan.damping), tensor(plan.implicit_damping)
        self.velocity_gain, self.chained = tensor(plan.velocity_gain), tensor(plan.chained)
        springs = plan.springs
        self.tendon_moment, self.tendon_stiffness = tensor(springs.moment), tensor(springs.stiffness)
        self.tendon_low, self.tendon_high = tensor(springs.rest[0]), tensor(springs.rest[1])
        self.tendon_damping = tensor(springs.damping)
        # (DoF, DoF): the tendons' dampers MuJoCo's step takes implicitly, on the DoF pairs of one chain
        implicit = (springs.moment.T * springs.implicit_damping) @ springs.moment
        self.tendon_implicit = tensor(implicit * plan.chained)
        self.any_tendon = bool(springs.stiffness.size)  # read on the host
        self._spatial(plan, tensor, device)
        self._rows(plan, tensor, device)
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

    def _spatial(self, plan: JointActuation, tensor, device) -> None:
        """The spatial tendons' arrays: their segments, the actuators pulling them, their springs and dampers."""
        spatial = plan.spatial
        self.spatial = SpatialTendonTensors(spatial.tendons, tensor, device)
        self.any_spatial = self.spatial.any  # read on the host
        self.spatial_actuated = torch.as_tensor(spatial.actuator >= 0, device=device)
        self.actuator_tendon = torch.as_tensor(np.maximum(spatial.actuator, 0), dtype=torch.long, device=device)
        self.spatial_gear = tensor(np.where(spatial.actuator >= 0, spatial.gear, 0.0))
        self.sprung = torch.as_tensor(spatial.sprung, dtype=torch.long, device=device)
        self.sprung_stiffness, self.sprung_damping = tensor(spatial.stiffness), tensor(spatial.damping)
        self.sprung_low, self.sprung_high = tensor(spatial.rest[0]), tensor(spatial.rest[1])
        self.sprung_implicit = tensor(spatial.implicit_damping)
        self.spatial_rows = SpatialRowSet(spatial.limits, spatial.friction, None, tensor, device)
        self.rowed = torch.as_tensor(spatial.rowed, dtype=torch.long, device=device)

    def _rows(self, plan: JointActuation, tensor, device) -> None:
        """The constraint rows' arrays: the limit and frictionloss rows of the DoFs and of the fixed tendons, the
        couplings and the connects."""
        tendons = plan.tendon_rows
        self.joint_rows = RowSet(plan.limits, plan.friction, None, tensor, device)
        self.tendon_rows = RowSet(tendons.limits, tendons.friction, tendons.moment, tensor, device)
        self.row_sets = [rows for rows in (self.joint_rows, self.tendon_rows) if rows.present]
        self.row_steps = tensor(ROW_STEPS)
        self.couplings = Couplings(plan.couplings, tensor)
        self.connects = Connects(plan.connects, tensor, device)
        self.welds = Welds(plan.welds, tensor, device)
        self.any_loops = self.connects.any or self.welds.any  # read on the host
        self.any_rows = bool(self.row_sets) or self.couplings.any or self.any_loops or self.spatial_rows.present


def next_activation(law: Law, ctrl: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
    """MuJoCo's activation one step on (`mj_nextActivation`) from `act` (env, nu) under `ctrl`: an integrator's rate
    is the clamped ctrl, a filter's (ctrl - act) / tau, stepped by Euler or, for filterexact, exactly; then held to
    actrange. An actuator without dynamics keeps its column."""
    ctrl = torch.clamp(ctrl, law.ctrl_low, law.ctrl_high)
    rate = torch.where(law.integrates, ctrl, (ctrl - act) / law.time_constant)
    stepped = act + rate * torch.where(law.exact, law.exact_step, torch.full_like(law.exact_step, law.timestep))
    return torch.where(law.activated, torch.clamp(stepped, law.act_low, law.act_high), act)


class Spatial(NamedTuple):
    """The spatial tendons at the state: their lengths (env, tendon) and Jacobians (env, tendon, n), every actuator's
    moment (env, nu, n: the plan's constant one, or its gear times its tendon's Jacobian) and the coordinates'
    speeds (env, n; a floating root's six first)."""

    length: torch.Tensor
    jacobian: torch.Tensor
    moment: torch.Tensor
    speed: torch.Tensor


def spatial_at(law: Law, inertia: Inertia, moved) -> Spatial:
    """The law's spatial tendons at the tree's `motion`."""
    length, jacobian = spatial_tendons(law.spatial, inertia, moved)
    root = moved.speed.shape[1] - law.moment.shape[1]
    pulled = jacobian[:, law.actuator_tendon] * law.spatial_gear[:, None]
    moment = torch.where(law.spatial_actuated[:, None], pulled, torch.nn.functional.pad(law.moment, (root, 0)))
    return Spatial(length, jacobian, moment, moved.speed)


def _actuation(
    law: Law,
    ctrl: torch.Tensor,
    q: torch.Tensor,
    v: torch.Tensor,
    act: torch.Tensor | None,
    spatial: Spatial | None = None,
):
    """The actuators' joint forces (env, DoF) at the state, each joint's sum within its actuatorfrcrange, and the
    actuators held to their forcerange (env, nu). An actuator with dynamics multiplies its activation (`act`, env x
    nu; None: zeros), or its next one where it acts early. A spatial tendon's length does not change as the whole
    tree moves: its moment has no share on a floating root's coordinates."""
    inputs = torch.clamp(ctrl, law.ctrl_low, law.ctrl_high)
    if law.any_activated:
        act = torch.zeros_like(inputs) if act is None else act
        act = torch.where(law.early, next_activation(law, ctrl, act), act)
        inputs = torch.where(law.activated, act, inputs)
    if spatial is None:
        length, rate = q @ law.moment.T, v @ law.moment.T
    else:
        pulled = spatial.length[:, law.actuator_tendon] * law.spatial_gear
        length = torch.where(law.spatial_actuated, pulled, q @ law.moment.T)
        rate = (spatial.moment @ spatial.speed[..., None])[..., 0]
    raw = law.gain * inputs + law.bias0 + law.bias1 * length + law.bias2 * rate
    force = torch.clamp(raw, law.force_low, law.force_high)
    if spatial is None:
        summed = force @ law.moment
    else:
        summed = (force[:, None, :] @ spatial.moment[..., -q.shape[1] :])[:, 0]
    return torch.clamp(summed, law.joint_low, law.joint_high), force != raw


def start_force(
    law: Law, ctrl: torch.Tensor, q: torch.Tensor, v: torch.Tensor, act: torch.Tensor | None = None
) -> torch.Tensor:
    """MuJoCo's actuator and passive force (env, DoF) at the state (q, v) (env, DoF) under `ctrl` (env, nu): the
    actuators' joint forces, each DoF's spring and its damper at v."""
    return _passive(law, q, v) + _actuation(law, ctrl, q, v, act)[0]


def _spatial_terms(law: Law, spatial: Spatial, clamped: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The spatial tendons' springs and dampers as a force on the coordinates (env, n), and what MuJoCo's step takes
    implicitly of them and of the actuators pulling them (env, n, n), a DoF pair's only where the two share a chain
    of the tree (a floating root's coordinates share every chain)."""
    jacobian = spatial.jacobian[:, law.sprung]  # (env, k, n)
    length = spatial.length[:, law.sprung]
    rate = (jacobian @ spatial.speed[..., None])[..., 0]
    stretched = torch.clamp(length, law.sprung_low, law.sprung_high) - length
    tension = law.sprung_stiffness * stretched - law.sprung_damping * rate
    force = (tension[:, None, :] @ jacobian)[:, 0]
    root = spatial.speed.shape[1] - law.moment.shape[1]
    chained = torch.nn.functional.pad(law.chained, (root, 0, root, 0), value=1.0)
    gains = law.velocity_gain * (~clamped).to(law.velocity_gain.dtype) * law.spatial_actuated
    pulled = (spatial.moment.transpose(-1, -2) * gains[:, None, :]) @ spatial.moment
    dampers = (jacobian.transpose(-1, -2) * law.sprung_implicit) @ jacobian
    return force, (pulled + dampers) * chained


def _passive(law: Law, q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """MuJoCo's passive force (env, DoF) at the state: each DoF's spring and damper, and each carried fixed tendon's
    spring (its deadband between its two rest lengths) and damper, through its coefficients."""
    force = law.stiffness * (law.spring_ref - q) - law.damping * v
    if law.any_tendon:
        length, rate = q @ law.tendon_moment.T, v @ law.tendon_moment.T
        stretched = torch.clamp(length, law.tendon_low, law.tendon_high) - length
        force = force + (law.tendon_stiffness * stretched - law.tendon_damping * rate) @ law.tendon_moment
    return force


def implicit_damping(law: Law, clamped: torch.Tensor) -> torch.Tensor:
    """D (env, DoF, DoF), the velocity derivative MuJoCo's step takes implicitly, negated: the dampers it integrates
    implicitly, and under the implicit integrators each actuator's -b2 m m^T and each carried tendon's damper
    d m m^T where the DoFs share a chain of the tree, an actuator's but where its forcerange binds (a joint's
    actuatorfrcrange binding leaves it in, as in MuJoCo)."""
    gains = law.velocity_gain * (~clamped).to(law.velocity_gain.dtype)  # (env, nu)
    actuators = ((law.moment.T * gains[:, None, :]) @ law.moment) * law.chained
    return actuators + torch.diag_embed(law.implicit_damping) + law.tendon_implicit


class ImplicitStep(NamedTuple):
    qf: torch.Tensor  # (env, DoF)
    end: torch.Tensor  # (env, DoF): v1
    matrix: torch.Tensor  # (env, n, n): M at the start, a floating root's six coordinates first
    bias: torch.Tensor  # (env, n): c
    force: torch.Tensor  # (env, n): f, the rows' force included (on a floating root's coordinates, the loops')

    def root_rows(self, q, v, pose, root_velocity, timestep: float) -> RootRows:
        """The free joint's rows of this step (`free_root.RootRows`), from the start's joint positions and velocities
        (env, ndof), root pose and free joint velocity: M, and c less f (the loops' rows' force on the root)."""
        return RootRows.solve(self.matrix, self.bias - self.force, q, v, pose, root_velocity, timestep)


def implicit_step(
    law: Law,
    inertia: Inertia,
    ctrl: torch.Tensor,
    q: torch.Tensor,
    v: torch.Tensor,
    root_pose: torch.Tensor,
    root_velocity: torch.Tensor | None = None,
    act: torch.Tensor | None = None,
) -> ImplicitStep:
    """MuJoCo's step of the joints from (q, v) under `ctrl` (no constraint rows): its end velocity v1 (env, DoF) from

        (M + dt D) (v1 - v0) = dt (f - c),

    f the actuator and passive force at the start, D its implicit derivative, M and c PhysX's inertia and bias at
    the state (`inertia.py`; a floating root's six coordinates first, no force on them), and the joint force
    `qf = M (v1 - v0) / dt + c` (env, DoF) that takes PhysX's joints there in one step, whatever its solver; M, c and
    f (the constraint rows' force in it) with them."""
    moved = motion(inertia, q, v, root_pose, root_velocity)  # one kinematic pass for M, c, tendons and loops
    spatial = spatial_at(law, inertia, moved) if law.any_spatial else None
    actuated, clamped = _actuation(law, ctrl, q, v, act, spatial)
    force = actuated + _passive(law, q, v)
    matrix, bias = mass_matrix_and_bias(inertia, q, v, root_pose, root_velocity, moved)
    root = matrix.shape[-1] - q.shape[-1]  # 6 for a floating root, else 0
    damping = law.timestep * implicit_damping(law, clamped)
    if root:  # no force and no damping on the root's coordinates
        damping = torch.nn.functional.pad(damping, (root, 0, root, 0))
        force = torch.nn.functional.pad(force, (root, 0))
    if spatial is not None:
        tendons, implicit = _spatial_terms(law, spatial, clamped)
        force, damping = force + tendons, damping + law.timestep * implicit
    if law.any_rows:
        force = force + constraint_force(law, matrix, q, v, force - bias, inertia, moved, spatial)
    change = torch.linalg.solve_ex(matrix + damping, law.timestep * (force - bias))[0]
    qf = ((matrix @ change[..., None])[..., 0] / law.timestep + bias)[:, root:]
    if root and law.any_loops:
        # PhysX's root takes no force: qf less what the loops' force on it, f_r, moves the joints by, M_jr M_rr^-1 f_r
        pushed = torch.linalg.solve_ex(matrix[:, :root, :root], force[:, :root])[0]
        qf = qf - (matrix[:, root:, :root] @ pushed[..., None])[..., 0]
    return ImplicitStep(qf, v + change[:, root:], matrix, bias, force)


class JointActuationController(BaseController):
    """Holds the last action as ctrl (env, nu); before every physics step, the law's `qf` for the robot's state and
    its drives aimed at MuJoCo's end velocity."""

    config: JointActuationConfig
    sets_target_qpos = False
    sets_target_qvel = False

    def _initialize_action_space(self):
        low, high = np.float32(self.config.low), np.float32(self.config.high)
        self.single_action_space = spaces.Box(low, high, dtype=np.float32)
        self.law = Law(self.config.plan, float(self.scene.timestep), self.device, LAW_DTYPE)
        self.ctrl = torch.zeros((self.scene.num_envs, len(self.config.low)), device=self.device, dtype=LAW_DTYPE)
        self.resetting: torch.Tensor | None = None  # the envs the agent's reset marked (`MJCFAgent.reset`)
        self.act = torch.zeros_like(self.ctrl)  # the actuators' activations (MuJoCo's act), per env
        self.inertia: Inertia | None = None  # the robot's M and c (`set_drive_property`)
        self.physx_joints: list | None = None  # on the CPU backend, the sub-scene's PhysX joints (`aim`)
        self.rows: RootRows | None = None  # a floating root's rows of the step under way (`settle`)
        self.link_names: tuple[str, ...] | None = None  # the robot's links, for their contacts (`touched`)

    def set_drive_property(self):
        """The drives hold the implicit damping alone (no stiffness; a velocity target each step); gravity on, as in
        MuJoCo, but on the links of fully compensated bodies, which the robot's M and c leave weightless too. The
        mode starts afresh: activations at zero, no step to settle."""
        self.act, self.rows = torch.zeros_like(self.act), None
        weightless = set(self.config.plan.weightless)
        for index, link in enumerate(self.articulation.links):
            link.disable_gravity = index in weightless
        tree = self.config.tree
        damping = np.where(turning_slides(tree), 0.0, self.config.plan.drive_damping)
        indices = self.active_joint_indices.cpu().numpy()
        for joint, held in zip(self.joints, damping[indices].tolist()):
            joint.set_drive_properties(0.0, held, force_limit=UNLIMITED, mode="force")
        floating = tree.floating and not bool(self.articulation.fixed_root_link[0])
        if floating != tree.floating:
            tree = replace(tree, floating=floating)
        gravity = self.scene.sim_config.scene_config.gravity
        self.inertia = Inertia(tree, gravity, weightless, self.device, LAW_DTYPE)

    @torch.inference_mode()
    def reset(self):
        """The envs an `env.reset` resets start as MuJoCo's reset starts them: ctrl and activations zero. ManiSkill
        marks those envs while it resets the agent and not while it resets the controllers, so the agent hands the
        mark on (`resetting`); without one, every env resets. The others run on untouched
        (tests/test_maniskill_joint_actuation.py::test_a_partial_reset_restarts_only_its_envs)."""
        envs, self.resetting = self.resetting, None
        if envs is None or bool(envs.all()):
            self.ctrl, self.act, self.rows = torch.zeros_like(self.ctrl), torch.zeros_like(self.act), None
            return
        envs = envs.to(self.device)
        self.ctrl[envs], self.act[envs] = 0.0, 0.0
        if self.rows is not None:  # a reset env's root stays where the reset put it
            self.rows.pending &= ~envs

    def set_action(self, action):
        self.ctrl = common.to_tensor(self._preprocess_action(action), device=self.device).to(LAW_DTYPE)

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

    def state(self) -> tuple[torch.Tensor, ...]:
        """The robot's joint positions and velocities, its root's pose and, where it floats, its root link's velocity
        (PhysX's convention), in the law's dtype (on the device: those of the last physics step)."""
        px, floating = self.scene.px, self.inertia.floating
        if self.scene.gpu_sim_enabled:
            px.gpu_fetch_articulation_qpos()
            px.gpu_fetch_articulation_qvel()
            px.gpu_fetch_articulation_link_pose()
            if floating:
                px.gpu_fetch_articulation_link_velocity()
        robot = self.articulation
        q, v = robot.get_qpos().to(LAW_DTYPE), robot.get_qvel().to(LAW_DTYPE)
        pose = robot.root_pose.raw_pose.to(LAW_DTYPE)
        if not floating:
            return q, v, pose, None
        return q, v, pose, torch.cat((robot.root_linear_velocity, robot.root_angular_velocity), -1).to(LAW_DTYPE)

    def settle(self) -> None:
        """The floating root of the last physics step as MuJoCo's step leaves it (`free_root.py`), in PhysX; the next
        physics step does it before it begins, a reader of the root's end state calls it first. Nothing where no
        step is pending."""
        if self.rows is not None:
            self._settled(*self.state())

    def _settled(self, q, v, pose, velocity) -> tuple[torch.Tensor, torch.Tensor]:
        """The root's pose and PhysX velocity after the pending step settled: MuJoCo's root in every env whose
        joints moved as PhysX's step moves them and whose tree no contact pushed, written into PhysX; PhysX's own
        elsewhere."""
        rows, self.rows = self.rows, None
        if rows is None:
            return pose, velocity
        gpu = self.scene.gpu_sim_enabled
        kept = rows.stepped(q, v) & ~self.touched()
        if not gpu and not bool(kept.any()):  # on the device, no host sync: every env is written
            return pose, velocity
        end_pose, end_velocity = rows.end(v)
        pose = torch.where(kept[:, None], end_pose, pose)
        velocity = torch.where(kept[:, None], physx_velocity(self.inertia, pose, end_velocity), velocity)
        robot = self.articulation
        robot.set_root_pose(Pose.create(pose.float()))
        robot.set_root_linear_velocity(velocity[:, :3].float())
        robot.set_root_angular_velocity(velocity[:, 3:].float())
        if gpu:
            px = self.scene.px
            px.gpu_apply_articulation_root_pose()
            px.gpu_apply_articulation_root_velocity()
            px.gpu_update_articulation_kinematics()
        else:
            robot.set_qvel(robot.get_qvel())  # the links' velocities follow the root's
        return pose, velocity

    def touched(self) -> torch.Tensor:
        """(env,) whether a contact pushed one of the robot's links in the last physics step."""
        if self.link_names is None:
            self.link_names = tuple(link.name for link in self.articulation.links)
        impulses = self.articulation.get_net_contact_impulses(self.link_names)
        return (impulses != 0).flatten(1).any(-1).to(self.device)

    @torch.inference_mode()  # no autograd bookkeeping: a third of the law's time on the CPU
    def before_simulation_step(self):
        """The last step settled; the state in; MuJoCo's step from it: `qf` out, and the drives aimed at its end
        velocity; the activations one step on."""
        q, v, pose, velocity = self.state()
        if velocity is not None:
            pose, velocity = self._settled(q, v, pose, velocity)
            velocity = free_velocity(self.inertia, pose, velocity)
        step = implicit_step(self.law, self.inertia, self.ctrl, q, v, pose, velocity, self.act)
        if velocity is not None:
            self.rows = step.root_rows(q, v, pose, velocity, self.law.timestep)
        self.aim(step.end)
        self.articulation.set_qf(step.qf.float())
        self.act = next_activation(self.law, self.ctrl, self.act)
        if self.scene.gpu_sim_enabled:
            px = self.scene.px
            px.gpu_apply_articulation_target_velocity()
            px.gpu_apply_articulation_qf()


@dataclass
class JointActuationConfig(ControllerConfig):
    low: list[float] = field(default_factory=list)  # ctrlrange (or -inf) per actuator
    high: list[float] = field(default_factory=list)
    plan: JointActuation | None = None
    tree: RigidTree | None = None  # the robot's rigid-body tree, for its M and c
    results: list = field(default_factory=list)  # the CPU backend's one LoadResult (its PhysX joints); none on GPU
    normalize_action: bool = False
    controller_cls = JointActuationController
