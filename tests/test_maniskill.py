"""The loader inside ManiSkill 3.0.1 (`loader.maniskill`, the `maniskill` extra), on the CPU: a Menagerie arm and
quadruped built into a ManiSkill scene as MuJoCo has them, `register_agent` robots in `Empty-v1` under every derived
control mode, the position servos' PD drives holding a keyframe as MuJoCo's servos do, and `mujoco_ctrl` following
MuJoCo stepped with the same ctrl at the scene's timestep. MuJoCo is the oracle. Skipped without mani_skill."""

from __future__ import annotations

import inspect
import json
import traceback
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
import sapien
from support.corpus import menagerie_root, suite_path
from support.oracle import POSE_TOLERANCE, collision_filter_mismatches, link_pose_errors

pytest.importorskip("mani_skill", reason="mani_skill is not installed (the `maniskill` extra)")
gym = pytest.importorskip("gymnasium")
torch = pytest.importorskip("torch")

import mani_skill
import mani_skill.envs  # registers Empty-v1
from mani_skill.envs.scene import ManiSkillScene
from mani_skill.envs.utils.system.backend import parse_sim_and_render_backend
from mani_skill.utils.structs.types import SimConfig

import loader as loader_package
from conformance import maniskill_loader
from conformance.tiers.maniskill import empty_env
from loader import SceneMismatchWarning, servos
from loader.maniskill import MJCFLoader, register_agent
from loader.plan import physx_settings

ROBOTS = {"panda": "franka_emika_panda/panda.xml", "go1": "unitree_go1/go1.xml"}
AGENTS = [*ROBOTS, "acrobot"]  # acrobot: a motor-only robot (dm_control's suite)
# rad, the largest |ManiSkill - MuJoCo| joint position over 1 s of the panda under pd_joint_delta_pos with zero
# actions from its keyframe, MuJoCo holding the keyframe's ctrl (its servos sag 6.6e-3 under gravity): measured
# 4.1e-5 (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0); with the arm's kp and kv swapped 4.5e-3
HOLD_TOLERANCE = 1e-4
# rad, the largest |ManiSkill - MuJoCo| joint position over 1 s under mujoco_ctrl (a 0.3 sine on the ctrl of the
# joint actuators around the first keyframe), MuJoCo at the scene's timestep on implicitfast: measured 4.4e-7 for
# the panda at 500 Hz (the model's) and at 100 Hz (ManiSkill's default), 4.4e-7 for the acrobot (same versions)
FOLLOW_TOLERANCE = 1e-5
# rad, the panda the same under ManiSkill's default scene configuration (TGS): measured 8.3e-6 at 500 Hz and
# 1.4e-5 at 100 Hz (same versions); with TGS stepping PhysX's drives 1.1e-2 and 0.24
TGS_FOLLOW_TOLERANCE = 1e-4
# rad, the panda under pd_joint_pos (a random walk of 0.1 % of each ctrl range per step from the keyframe, at the
# model's 500 Hz) under ManiSkill's default scene configuration, MuJoCo stepping the same ctrl: the target.
# Measured 8.9e-4 (same versions); with the drives' damping left at the servo's (no - K dt) 1.4e-3
PD_FOLLOW_TOLERANCE = 1e-3


def _path(robot: str):
    if robot not in ROBOTS:
        return suite_path(robot)
    root = menagerie_root()
    if root is None or not (root / ROBOTS[robot]).is_file():
        pytest.skip("Menagerie slice not installed")
    return root / ROBOTS[robot]


def _cpu_scene(timestep: float) -> ManiSkillScene:
    """A one-sub-scene CPU ManiSkill scene as ManiSkill's env makes it, with MuJoCo's solver (PGS) and gravity."""
    previous = sapien.physx.get_scene_config()
    sapien.physx.set_scene_config(gravity=[0.0, 0.0, -9.81], enable_tgs=False)
    try:
        sub_scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    finally:
        sapien.physx.set_scene_config(previous)
    scene = ManiSkillScene(
        [sub_scene],
        sim_config=SimConfig(),
        device=torch.device("cpu"),
        backend=parse_sim_and_render_backend("physx_cpu", "none"),
    )
    scene.timestep = timestep
    return scene


@pytest.fixture(scope="module")
def agents():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {robot: register_agent(_path(robot), f"mjcf_{robot}", override=True) for robot in AGENTS}


def _env(uid: str, mode: str, sim_freq: int, control_freq: int, tgs: bool = False):
    """`Empty-v1` with the robot; PGS, or with `tgs` ManiSkill's default scene configuration."""
    return empty_env(uid, mode, sim_freq, control_freq, None if tgs else {"enable_tgs": False})


@pytest.mark.parametrize("robot", ROBOTS)
def test_an_arm_and_a_quadruped_load_into_a_maniskill_scene_as_in_mujoco(robot, rng):
    path = _path(robot)
    model = mujoco.MjModel.from_xml_path(str(path))
    loader = MJCFLoader()
    loader.set_scene(_cpu_scene(float(model.opt.timestep)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        articulation = loader.load(str(path), name=robot)
    (result,) = loader.results
    free = int(np.sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))
    assert articulation.max_dof == model.nv - 6 * free
    qpos = rng.uniform(-0.1, 0.1, articulation.max_dof).astype(np.float32)
    result.articulations[0].set_qpos(qpos)
    np.testing.assert_array_equal(articulation.get_qpos()[0].numpy(), qpos)  # the result's is ManiSkill's robot
    assert link_pose_errors(result, rng, 3) < (POSE_TOLERANCE, POSE_TOLERANCE)
    assert collision_filter_mismatches(result) == []
    links = result.articulations[0].links
    masses = np.zeros(len(links))
    for body in range(1, model.nbody):
        masses[result.mapping.bodies[body].link] += model.body_mass[body]
    np.testing.assert_allclose([link.mass for link in links], masses, rtol=1e-6, atol=1e-6)  # helpers: ~0 kg
    joints = result.articulations[0].active_joints
    for j in range(model.njnt):
        for dof in result.mapping.joints[j].dofs:
            assert joints[dof].armature[0] == pytest.approx(model.dof_armature[model.jnt_dofadr[j]], rel=1e-6)


@pytest.mark.parametrize("robot", AGENTS)
def test_every_derived_control_mode_makes_an_empty_env(robot, agents):
    """Each actuator is one action in every mode (a coupled gripper one, a motor-only robot's PD modes on the
    joints its motors drive)."""
    agent_class = agents[robot]
    model = mujoco.MjModel.from_xml_path(agent_class.mjcf_path)
    modes = ["pd_joint_pos", "pd_joint_delta_pos", "mujoco_ctrl"]
    for mode in modes:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = _env(agent_class.uid, mode, 500, 100)
        try:
            env.reset(seed=0)
            agent = env.unwrapped.agent
            assert mode in agent.supported_control_modes
            assert env.action_space.shape == (model.nu,)
            env.step(env.action_space.sample() * 0)
            assert torch.isfinite(agent.robot.get_qpos()).all()
        finally:
            env.close()
    assert set(agent_class.keyframes) == {model.key(k).name for k in range(model.nkey)}


def test_an_arm_holds_its_keyframe_under_zero_delta_actions_as_in_mujoco(agents):
    agent_class = agents["panda"]
    model = mujoco.MjModel.from_xml_path(agent_class.mjcf_path)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = _env(agent_class.uid, "pd_joint_delta_pos", 500, 100)
    try:
        env.reset(seed=0)
        agent = env.unwrapped.agent
        agent.robot.set_qpos(agent_class.keyframes[model.key(0).name].qpos)
        agent.controller.reset()
        worst = 0.0
        for _ in range(100):
            env.step(np.zeros(env.action_space.shape))
            for _ in range(5):
                mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(agent.results[0].get_state()[0] - data.qpos).max()))
    finally:
        env.close()
    assert worst < HOLD_TOLERANCE


def _follow(agent_class, sim_freq: int, tgs: bool, mujoco_step: bool = True) -> tuple[float, bool]:
    """The largest |ManiSkill - MuJoCo| joint position over 1 s of `mujoco_ctrl` (a sine on the joint actuators'
    ctrl around the first keyframe), MuJoCo stepped with the same ctrl at the scene's timestep; the joint forces
    from MuJoCo's own step (the mode's default, where the robot allows) or from the per-step terms; and whether MuJoCo's
    step gave them."""
    model = mujoco.MjModel.from_xml_path(agent_class.mjcf_path)
    file_timestep = model.opt.timestep
    model.opt.timestep = 1.0 / sim_freq
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # what the mapping assumes (the acrobot's RK4
    # is approximated by it: docs/mapping.md#integrators)
    data = mujoco.MjData(model)
    key = 0 if model.nkey else None
    if key is not None:
        mujoco.mj_resetDataKeyframe(model, data, key)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = _env(agent_class.uid, "mujoco_ctrl", sim_freq, 100, tgs)
    mismatch = [w for w in caught if issubclass(w.category, SceneMismatchWarning)]
    assert bool(mismatch) == (np.float32(1.0 / sim_freq) != np.float32(file_timestep)), "another timestep is warned"
    try:
        env.reset(seed=0)
        (result,) = env.unwrapped.agent.results
        if not mujoco_step:
            result.controller.use_mujoco_step(False)
        result.reset(key)
        around = model.key_ctrl[0] if key is not None else np.zeros(model.nu)
        joint_actuators = model.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT
        worst = 0.0
        for step in range(100):
            ctrl = (around + 0.3 * np.sin(2 * np.pi * step / 50) * joint_actuators).astype(np.float32)
            env.step(ctrl)
            data.ctrl[:] = ctrl
            for _ in range(sim_freq // 100):
                mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(result.get_state()[0] - data.qpos).max()))
        whole = result.controller.whole is not None
    finally:
        env.close()
    return worst, whole


@pytest.mark.parametrize(("robot", "sim_freq"), [("panda", 500), ("panda", 100), ("acrobot", 100)])
def test_mujoco_ctrl_follows_mujoco_stepping_the_same_ctrl(agents, robot, sim_freq):
    worst, whole = _follow(agents[robot], sim_freq, tgs=False)
    assert worst < FOLLOW_TOLERANCE
    assert whole  # the acrobot too: no rows (a copy made for the step), RK4 run as Euler


@pytest.mark.parametrize("mujoco_step", [True, False], ids=["mujoco_step", "terms"])
@pytest.mark.parametrize("sim_freq", [500, 100])
def test_mujoco_ctrl_follows_mujoco_under_maniskills_default_solver(agents, sim_freq, mujoco_step, monkeypatch):
    """README's example as written: ManiSkill's default scene configuration steps with TGS. The mode's joint forces
    come from MuJoCo's own step (loader/runtime/mujoco_step.py), or from the terms, which write the drives as joint
    forces under TGS (loader/runtime/drive_forces.py); with TGS left to step the terms' drives, the panda does not
    follow."""
    worst, whole = _follow(agents["panda"], sim_freq, tgs=True, mujoco_step=mujoco_step)
    assert worst < TGS_FOLLOW_TOLERANCE and whole == mujoco_step
    if not mujoco_step:
        monkeypatch.setattr(physx_settings, "uses_tgs", lambda scene: False)
        assert _follow(agents["panda"], sim_freq, tgs=True, mujoco_step=False)[0] > 10 * TGS_FOLLOW_TOLERANCE


def _pd_walk(agent_class, sim_freq: int = 500) -> float:
    """The largest |ManiSkill - MuJoCo| joint position over 0.5 s of `pd_joint_pos` (ManiSkill's default scene
    configuration) under a seeded random walk of the ctrl from the keyframe, each action the position servos'
    targets for it (`Servo.target`), MuJoCo stepping the ctrl itself."""
    model = mujoco.MjModel.from_xml_path(agent_class.mjcf_path)
    model.opt.timestep = 1.0 / sim_freq
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = _env(agent_class.uid, "pd_joint_pos", sim_freq, sim_freq, tgs=True)
    try:
        env.reset(seed=0)
        agent = env.unwrapped.agent
        agent.robot.set_qpos(agent_class.keyframes[model.key(0).name].qpos)
        agent.controller.reset()
        rng, (low, high), ctrl = np.random.default_rng(0), model.actuator_ctrlrange.T, data.ctrl.copy()
        worst = 0.0
        for _ in range(sim_freq // 2):
            ctrl = np.clip(ctrl + 1e-3 * rng.standard_normal(model.nu) * (high - low), low, high)
            env.step(np.array([s.target(ctrl[s.index]) for s in agent_class.servos if s.kind == "position"]))
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(agent.results[0].get_state()[0] - data.qpos).max()))
    finally:
        env.close()
    return worst


def test_pd_joint_pos_follows_mujoco_on_the_panda(agents, monkeypatch):
    """The PD mode as GPU users run it: each position servo a PhysX drive whose damping is the servo's less K dt
    (`Servo.physx_damping`), so that PhysX's implicit drive steps as MuJoCo's servo; with the servo's own damping
    the arm falls behind."""
    assert _pd_walk(agents["panda"]) < PD_FOLLOW_TOLERANCE
    monkeypatch.setattr(servos.Servo, "physx_damping", lambda servo, timestep: list(servo.damping))
    assert _pd_walk(agents["panda"]) > PD_FOLLOW_TOLERANCE


# Two motors push a planar arm into its joints' limits, whose soft rows let MuJoCo's elbow 0.5 rad past its end
LIMITED_ARM = """<mujoco model="limited_arm">
  <compiler angle="radian"/>
  <option timestep="0.002"/>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" axis="0 1 0" range="-0.5 0.5"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" mass="1"/>
      <body name="fore" pos="0.3 0 0">
        <joint name="elbow" axis="0 1 0" range="-0.8 0.8"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="shoulder" gear="20" ctrlrange="-1 1"/>
    <motor joint="elbow" gear="10" ctrlrange="-1 1"/>
  </actuator>
</mujoco>"""
# rad, the largest |ManiSkill - MuJoCo| joint position of the limited arm over 0.5 s of `mujoco_ctrl_tensor` in an env
# made in `pd_joint_pos` and switched by ManiSkill's {"control_mode", "action"} step (TGS, full ctrl in and out of the
# limits): measured 2.1e-6 (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0, torch 2.13.0); with PhysX's hard limits
# left at the range 0.51
SWITCH_TOLERANCE = 1e-4


def _limited_arm_env(uid: str, mode: str):
    """`Empty-v1` (TGS, 500 Hz, control at 50 Hz) with `LIMITED_ARM` registered as `uid`, made in `mode`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(mujoco.MjSpec.from_string(LIMITED_ARM), uid, override=True)
        return _env(agent.uid, mode, 500, 50, tgs=True)


def _drive_state(agent) -> list:
    """What a mode sets on the robot: each joint's drive and limits, each link's gravity, the joint forces."""
    joints = agent.results[0].articulations[0].get_active_joints()
    return [
        [(float(j.stiffness), float(j.damping), float(j.force_limit), j.limit.tolist()) for j in joints],
        [bool(link.disable_gravity.all()) for link in agent.robot.links],
        agent.robot.get_qf()[0].tolist(),
    ]


@pytest.mark.parametrize("mistake", [None, "limits_left", "not_handed_back", "drives_left"])
def test_a_switch_of_control_mode_sets_the_modes_drives_and_limits(monkeypatch, mistake):
    """ManiSkill switches a mode by a step's {"control_mode", "action"}, and sets a mode's drives only when it first
    makes it. An env made in `pd_joint_pos` and switched to `mujoco_ctrl_tensor` follows MuJoCo with motors pushing
    past the soft limits, and switched back, PD holds the drives, gravity, limits and (no) joint forces it was made
    with. Each mistake fails it: PhysX's hard limits left at the range under the law, the joints not handed back on
    leaving it (`release()`), a mode made before not set again."""
    from loader.maniskill import agent as agent_module

    if mistake == "limits_left":
        monkeypatch.setattr(agent_module.MJCFAgent, "_limits_for", lambda agent, mode, gpu: None)
    elif mistake == "not_handed_back":
        monkeypatch.setattr(agent_module, "LAWS", ())
    elif mistake == "drives_left":
        monkeypatch.setattr(agent_module.MJCFAgent, "_resume", lambda agent, mode: None)
    model = mujoco.MjModel.from_xml_string(LIMITED_ARM)
    data = mujoco.MjData(model)
    env = _limited_arm_env(f"switched_arm_{mistake}", "pd_joint_pos")
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent
        made, worst = _drive_state(robot), 0.0
        for step in range(25):
            ctrl = np.array([1.0, -1.0] if step < 15 else [-1.0, 1.0], np.float32)
            env.step({"control_mode": "mujoco_ctrl_tensor", "action": ctrl})
            data.ctrl[:] = ctrl
            for _ in range(10):
                mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(robot.robot.get_qpos()[0].numpy() - data.qpos).max()))
        env.step({"control_mode": "pd_joint_pos", "action": np.zeros(2, np.float32)})
        back = _drive_state(robot)
    finally:
        env.close()
    assert (worst < SWITCH_TOLERANCE and back == made) == (mistake is None), (worst, made, back)


@pytest.mark.parametrize("mistake", [None, "not_handed_back"])
def test_an_env_made_in_the_tensor_mode_gives_pd_its_hard_limits(monkeypatch, mistake):
    """An env made in `mujoco_ctrl_tensor` builds its limited joints free of PhysX's limits; switched to a PD mode,
    PhysX holds MuJoCo's range again. Not handed back, the joints keep no limit."""
    from loader.maniskill import agent as agent_module

    if mistake:
        monkeypatch.setattr(agent_module, "LAWS", ())
    env = _limited_arm_env(f"tensor_made_arm_{mistake}", "mujoco_ctrl_tensor")
    try:
        env.reset(seed=0)
        env.step({"control_mode": "pd_joint_pos", "action": np.zeros(2, np.float32)})
        joints = env.unwrapped.agent.results[0].articulations[0].get_active_joints()
        limits = np.array([joint.limit[0] for joint in joints])
    finally:
        env.close()
    assert np.array_equal(limits, np.float32(mujoco.MjModel.from_xml_string(LIMITED_ARM).jnt_range)) == (not mistake)


@pytest.mark.parametrize("made", ["pd_joint_pos", "mujoco_ctrl_tensor"])
def test_on_the_gpu_a_switch_that_needs_other_limits_is_warned(made):
    """On physx_cuda PhysX keeps the limits and D6 joints an env was built with, so a switch into or out of the tensor
    mode that would need others warns, naming the control mode to make the env with; a switch that needs none is
    silent. The GPU's branch of the switch, taken on the CPU backend's env."""
    from loader import UnsupportedFeatureWarning

    env = _limited_arm_env(f"gpu_switch_{made}", made)
    try:
        agent = env.unwrapped.agent
        other = "pd_joint_pos" if made == "mujoco_ctrl_tensor" else "mujoco_ctrl_tensor"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            agent._limits_for(made, gpu=True)
            assert not caught
            agent._limits_for(other, gpu=True)
        (warned,) = [w for w in caught if issubclass(w.category, UnsupportedFeatureWarning)]
        assert f"control_mode={other!r}" in str(warned.message) and "joint limits" in str(warned.message)
    finally:
        env.close()


CLOSED_CHAIN = Path(__file__).resolve().parents[1] / "corpus" / "fixtures" / "closed_chain.xml"
# m, the largest distance between the closed chain's two pin anchors over 1 s under pd_joint_pos with the hip swung
# (TGS), its connect a D6 joint locked as `release()` locks it: measured 1.3e-6 (mani-skill 3.0.1, sapien 3.0.3,
# mujoco 3.17.0); with no lock 0.35
PIN_TOLERANCE = 1e-4


def _pin_gap(uid: str) -> float:
    """The largest distance between the closed chain's pin anchors over 1 s under pd_joint_pos (ManiSkill's PD on
    the hip, its links weightless), the hip's target a 0.5 rad sine."""
    model = mujoco.MjModel.from_xml_path(str(CLOSED_CHAIN))
    anchors = model.eq_data[0][:3], model.eq_data[0][3:6]  # the pin in each lower leg's frame
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = _env(uid, "pd_joint_pos", 500, 50, tgs=True)
    try:
        env.reset(seed=0)
        links, worst = env.unwrapped.agent.robot.links_map, 0.0
        for step in range(50):
            env.step(np.array([0.5 * np.sin(2 * np.pi * step / 25)], np.float32))
            ends = [
                links[name].pose.sp * sapien.Pose(anchor)
                for name, anchor in zip(("left_lower", "right_lower"), anchors)
            ]
            worst = max(worst, float(np.linalg.norm(ends[0].p - ends[1].p)))
    finally:
        env.close()
    return worst


@pytest.mark.parametrize("mistake", [None, "no_locks"])
def test_the_gpu_build_holds_a_closed_loop_with_locked_d6_joints(monkeypatch, mistake):
    """ManiSkill's GPU backend runs no per-step term, so its build holds the model's connects and welds as the D6
    joints `release()` locks on the CPU backend (`lock_loops`). Built that way on the CPU backend, with no
    `LoadResult`, the closed chain's five-bar swung by its hip under `pd_joint_pos` keeps its pin closed exactly as
    the CPU build does, bit for bit; with no lock built, it opens."""
    from loader.maniskill import scene_loader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(CLOSED_CHAIN, f"gpu_built_chain_{mistake}", override=True)
    cpu_built = _pin_gap(agent.uid)
    monkeypatch.setattr(scene_loader, "per_step_terms", lambda scene: False)
    if mistake:
        monkeypatch.setattr(scene_loader, "lock_loops", lambda parsed, scene, articulation, standing_by: [])
    gpu_built = _pin_gap(agent.uid)
    assert cpu_built < PIN_TOLERANCE
    assert (gpu_built == cpu_built) == (gpu_built < PIN_TOLERANCE) == (mistake is None), (gpu_built, cpu_built)


def test_on_the_gpu_physx_holds_the_build_time_settings_in_every_sub_scene(agents):
    if not torch.cuda.is_available():
        pytest.skip("needs CUDA (ManiSkill's physx_cuda backend)")
    agent_class = agents["panda"]
    model = mujoco.MjModel.from_xml_path(agent_class.mjcf_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = empty_env(agent_class.uid, "pd_joint_delta_pos", 100, 20, backend="physx_cuda", num_envs=2)
    try:
        env.reset(seed=0)
        assert "mujoco_ctrl" not in env.unwrapped.agent.supported_control_modes
        assert sum("CPU-only" in str(w.message) for w in caught) == 1
        for sub_scene in env.unwrapped.scene.sub_scenes:
            links = [
                c
                for entity in sub_scene.entities
                for c in entity.components
                if isinstance(c, sapien.physx.PhysxArticulationLinkComponent)
            ]
            articulation = links[0].articulation  # Empty-v1's only articulation: the robot
            armature = [joint.armature[0] for joint in articulation.active_joints]
            np.testing.assert_allclose(armature, model.dof_armature, rtol=1e-6)
    finally:
        env.close()


def test_on_the_gpu_a_closed_loop_holds_in_every_sub_scene():
    """On physx_cuda the closed chain's connect is a locked D6 joint in each sub-scene: swung by its hip under
    `pd_joint_pos`, every sub-scene keeps its pin within `PIN_TOLERANCE`."""
    if not torch.cuda.is_available():
        pytest.skip("needs CUDA (ManiSkill's physx_cuda backend)")
    from mani_skill.utils.geometry.rotation_conversions import quaternion_to_matrix

    model = mujoco.MjModel.from_xml_path(str(CLOSED_CHAIN))
    anchors = [torch.as_tensor(model.eq_data[0][k : k + 3], dtype=torch.float32, device="cuda") for k in (0, 3)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(CLOSED_CHAIN, "gpu_chain", override=True)
        env = empty_env(agent.uid, "pd_joint_pos", 500, 50, backend="physx_cuda", num_envs=4)
    try:
        env.reset(seed=0)
        links, worst = env.unwrapped.agent.robot.links_map, 0.0
        for step in range(50):
            env.step(torch.full((4, 1), 0.5 * np.sin(2 * np.pi * step / 25), device="cuda"))
            ends = []
            for name, anchor in zip(("left_lower", "right_lower"), anchors):
                pose = links[name].pose
                rotation = quaternion_to_matrix(pose.q)  # (w, x, y, z), as ManiSkill's poses hold it
                ends.append(pose.p + (rotation @ anchor[:, None])[..., 0])
            worst = max(worst, float(torch.linalg.vector_norm(ends[0] - ends[1], dim=-1).max()))
    finally:
        env.close()
    assert worst < PIN_TOLERANCE, worst


def test_a_maniskill_scene_is_asked_for_rendering_through_its_sub_scenes():
    """Where a render device exists the loader asks whether the scene renders: a ManiSkill scene answers for its
    sub-scenes (it has no `get_system` of its own). A sub-scene without a render system does not render."""
    from loader.plan.visual import scene_renders

    assert scene_renders(_cpu_scene(0.002)) is False


SPINNER = """<mujoco model="spinner"><option timestep="0.002" integrator="implicitfast"/>
  <worldbody><body name="base" pos="0.3 0.2 1"><geom type="box" size="0.05 0.05 0.05" contype="0" conaffinity="0"/>
    <body name="rotor" pos="0 0 0.1"><joint name="spin" axis="0 0 1" damping="0.2" armature="0.01"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" contype="0" conaffinity="0"/></body></body></worldbody>
  <actuator><velocity name="speed" joint="spin" kv="2" ctrlrange="-3 3"/></actuator></mujoco>"""
# rad/s, the largest |ManiSkill - MuJoCo| joint velocity over 1 s of SPINNER under pd_joint_vel (a sine over 70% of
# ctrlrange), MuJoCo given the ctrl the normalized action stands for: measured 5.7e-7 (same versions); with the
# target not scaled for the joint's damping on the drive 0.18
VELOCITY_TOLERANCE = 1e-5


def test_a_velocity_servo_drives_pd_joint_vel_as_in_mujoco(tmp_path):
    """The action is the ctrl normalized over ctrlrange; the drive's damping is kv plus the joint's, so the
    target is scaled by kv / (kv + damping) (`loader/servos.py`). The env's pose places the file's world
    frame: the fixed base stays where the file puts it."""
    (tmp_path / "spinner.xml").write_text(SPINNER)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        register_agent(tmp_path / "spinner.xml", "mjcf_spinner", override=True)
        env = _env("mjcf_spinner", "pd_joint_vel", 500, 100)
    model = mujoco.MjModel.from_xml_string(SPINNER)
    data = mujoco.MjData(model)
    low, high = model.actuator_ctrlrange[0]
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent.robot
        placed = link_pose_errors(env.unwrapped.agent.results[0], np.random.default_rng(0), 0)
        assert placed < (POSE_TOLERANCE, POSE_TOLERANCE), "the env's pose places the file's world frame"
        worst = 0.0
        for step in range(100):
            action = np.float32(0.7 * np.sin(2 * np.pi * step / 50))
            env.step(np.array([action]))
            data.ctrl[0] = low + (float(action) + 1.0) / 2.0 * (high - low)
            for _ in range(5):
                mujoco.mj_step(model, data)
            worst = max(worst, abs(float(robot.get_qvel()[0, 0]) - data.qvel[0]))
    finally:
        env.close()
    assert worst < VELOCITY_TOLERANCE


def test_disable_self_collisions_filters_every_pair_of_the_robot_as_maniskill_means_it():
    """ManiSkill's option: no link of the robot touches another. With it, the only differences from MuJoCo's
    collision filter are pairs MuJoCo lets touch and PhysX now does not."""
    path = _path("panda")
    loader = MJCFLoader()
    loader.set_scene(_cpu_scene(0.002))
    loader.disable_self_collisions = True
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loader.load(str(path), name="panda_alone")
    mismatches = collision_filter_mismatches(loader.results[0])
    assert mismatches and all(physx is False for _, _, physx in mismatches)


# ManiSkill's own MJCF files, environments and agents with this loader in its place

MANISKILL = Path(mani_skill.__file__).parent
SHIPPED = sorted(
    path
    for path in MANISKILL.rglob("*.xml")
    if path.read_text(errors="replace").lstrip().startswith("<mujoco")
    and "<worldbody" in path.read_text(errors="replace")
)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda path: str(path.relative_to(MANISKILL)))
def test_names_and_dof_order_match_maniskills_loader(path):
    """Every MJCF model ManiSkill ships: its links (`dummy_root_<i>`, `<body>_dummy_<k>`) and its joints in DoF
    order, as ManiSkill's own loader names and orders them, so that task code and keyframes written against it
    line up (`maniskill_dialect`, loader/plan/tree.py)."""
    loader = MJCFLoader()
    loader.set_scene(_cpu_scene(0.002))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        articulation = loader.load(str(path), name="robot")
    (result,) = loader.results
    scene, theirs, _, _ = maniskill_loader.build(str(path), result.model)  # its articulations live with `scene`
    assert list(articulation.links_map) == [link.name for link in theirs[0].links]
    assert list(articulation.active_joints_map) == [joint.name for joint in theirs[0].active_joints]
    del scene


def _mjcf_envs() -> list:
    """The environments ManiSkill registers whose task module builds from MJCF; skipped where the assets ManiSkill
    would ask to download are not installed."""
    from mani_skill.utils import assets
    from mani_skill.utils.registration import REGISTERED_ENVS

    params = []
    for uid, spec in sorted(REGISTERED_ENVS.items()):
        if "mjcf" not in inspect.getsource(inspect.getmodule(spec.cls)).lower():
            continue
        sources = [
            source
            for asset in spec.asset_download_ids or []
            for source in (
                assets.expand_data_group_into_individual_data_source_ids(asset)
                if asset in assets.DATA_GROUPS
                else [asset]
            )
        ]
        missing = [source for source in sources if not assets.is_data_source_downloaded(source)]
        reason = f"ManiSkill's downloadable assets {missing} are not installed"
        params.append(pytest.param(uid, marks=[pytest.mark.skip(reason=reason)] if missing else []))
    return params


def _needs_a_render_device(error: RuntimeError) -> bool:
    """Whether the task's own code (not this loader's) asked for a render device."""
    frames = [Path(frame.filename) for frame in traceback.extract_tb(error.__traceback__)]
    package = Path(loader_package.__file__).parent
    return "rendering device" in str(error) and not any(frame.is_relative_to(package) for frame in frames)


@pytest.mark.parametrize("uid", _mjcf_envs())
def test_every_mjcf_env_builds_resets_and_steps_with_this_loader(uid, monkeypatch):
    """`ManiSkillScene.create_mjcf_loader` returns this loader; each MJCF task builds, resets and steps on the CPU
    under its default control mode (a PD mode: the joints released to PhysX with MuJoCo's limits)."""

    def create(scene):
        return MJCFLoader().set_scene(scene)

    monkeypatch.setattr(ManiSkillScene, "create_mjcf_loader", create)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = gym.make(uid, sim_backend="physx_cpu", render_backend="none", obs_mode="state", num_envs=1)
            env.reset(seed=0)
    except RuntimeError as error:
        if not _needs_a_render_device(error):
            raise
        pytest.skip("the task's own scene code needs a render device")
    try:
        torch.manual_seed(0)
        for _ in range(10):
            obs, reward, *_ = env.step(env.action_space.sample())
        assert torch.isfinite(obs).all() and torch.isfinite(reward).all()
        assert "dummy_root_0" in env.unwrapped.agent.robot.links_map
    finally:
        env.close()


def _mjcf_agents() -> list:
    """The agents ManiSkill registers with an MJCF file; skipped where the file is a download not installed."""
    from mani_skill.agents.registration import REGISTERED_AGENTS

    params = []
    for uid, entry in sorted(REGISTERED_AGENTS.items()):
        path = getattr(entry.agent_cls, "mjcf_path", None)
        if path is None:
            continue
        missing = [pytest.mark.skip(reason=f"{path} is a ManiSkill download, not installed")]
        params.append(pytest.param(uid, marks=[] if Path(path).is_file() else missing))
    return params


@pytest.mark.parametrize("uid", _mjcf_agents())
def test_every_mjcf_agent_builds_resets_and_steps_with_this_loader(uid, monkeypatch):
    """Each MJCF agent ManiSkill ships, in `Empty-v1` under its default control mode, with its keyframes' qpos in
    this loader's DoF order."""
    monkeypatch.setattr(ManiSkillScene, "create_mjcf_loader", lambda scene: MJCFLoader().set_scene(scene))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make("Empty-v1", robot_uids=uid, sim_backend="physx_cpu", render_backend="none", obs_mode="state")
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent.robot
        for keyframe in env.unwrapped.agent.keyframes.values():
            assert len(keyframe.qpos) == robot.max_dof
        torch.manual_seed(0)
        for _ in range(10):
            env.step(env.action_space.sample())
        assert torch.isfinite(robot.get_qpos()).all()
    finally:
        env.close()


# ManiSkill's own loader judged by the harness (`run --loader maniskill`, conformance/maniskill_loader.py)

TILTED = """<mujoco model="tilted"><option timestep="0.002"/>
  <worldbody><body name="arm" pos="0 0 1" {orientation}><joint name="swing" axis="0 0 1"/>
    <geom type="box" size="0.1 0.05 0.02"/>
    <body name="hand" pos="0.2 0 0"><joint name="wrist" axis="1 0 0"/><geom type="sphere" size="0.03"/></body>
  </body></worldbody></mujoco>"""
PITCH = 30.0  # degrees about y, written as `euler` or as the same rotation's quaternion
ROBOT = """<mujoco><worldbody><body name="upper" pos="0 0 0.5"><joint name="shoulder" axis="0 1 0"/>
  <geom type="capsule" size="0.02 0.1"/></body></worldbody></mujoco>"""
SCENE = """<mujoco model="scene">{robot}<worldbody><geom name="floor" type="plane" size="1 1 0.1"/></worldbody>
  </mujoco>"""


def _tier(tmp_path, path, tier, loader="maniskill"):
    from conformance.manifest import ModelEntry
    from conformance.worker import Job, evaluate

    entry = ModelEntry(id=Path(path).stem, source=str(path), tiers=(tier,))
    result = evaluate(Job(entry, str(path), str(tmp_path), 0, (tier,), record=False, loader=loader))
    assert result.status == "ok", result.reason
    return result.tiers[tier]


def _max(report, name):
    return next(m["max"] for m in report["metrics"] if m["name"] == name)


def test_maniskills_loader_turns_an_euler_pitch_the_other_way(tmp_path):
    """ManiSkill's `_parse_orientation` negates the second Euler angle: a body pitched by `euler` sits pitched the
    other way, 2 x PITCH from MuJoCo's, while the same rotation written as a quaternion is where MuJoCo has it."""
    from mani_skill.utils.building import _mjcf_loader

    half = np.radians(PITCH) / 2
    for name, orientation in (("euler", f'euler="0 {PITCH} 0"'), ("quat", f'quat="{np.cos(half)} 0 {np.sin(half)} 0"')):
        (tmp_path / f"{name}.xml").write_text(TILTED.format(orientation=orientation))
    euler = _tier(tmp_path, tmp_path / "euler.xml", "kinematics")
    assert euler["status"] == "fail"
    assert _max(euler, "orientation") == pytest.approx(np.radians(2 * PITCH), abs=1e-4)
    assert _tier(tmp_path, tmp_path / "quat.xml", "kinematics")["status"] == "pass"
    assert _tier(tmp_path, tmp_path / "euler.xml", "kinematics", loader="ours")["status"] == "pass"
    assert _mjcf_loader.RenderMaterial is sapien.render.RenderMaterial, "the render stand-in is put back"


def test_maniskills_loader_loses_the_bodies_of_an_included_file(tmp_path):
    """ManiSkill's loader appends an included file's elements after the including file's own `<worldbody>` and reads
    only the first: the included robot is not built. Inline it is."""
    (tmp_path / "robot.xml").write_text(ROBOT)
    (tmp_path / "scene.xml").write_text(SCENE.format(robot='<include file="robot.xml"/>'))
    inline = ROBOT.removeprefix("<mujoco>").removesuffix("</mujoco>")
    (tmp_path / "inline.xml").write_text(SCENE.format(robot=inline))
    included = _tier(tmp_path, tmp_path / "scene.xml", "structure")
    assert included["status"] == "fail"
    assert _max(included, "mismatches") >= 2  # the body and its joint
    assert any("'upper'" in note for note in included["notes"])
    assert _tier(tmp_path, tmp_path / "inline.xml", "structure")["status"] == "pass"


def _run(tmp_path, *args):
    from conformance.cli import main

    code = main(["run", *args, "--out", str(tmp_path / "out"), "--quiet", "--no-record", "--jobs", "1"])
    return code, tmp_path / "out" / "latest"


def test_the_loader_maniskill_runs_corpus_models_and_fails_where_maniskill_is_wrong(tmp_path):
    """The manipulator's thumb is pitched by `euler="0 -90 0"`: ManiSkill's loader turns it +90, half a turn from
    MuJoCo's. The pendulum's actuator is skipped with why; nothing raises."""
    import json

    code, run = _run(
        tmp_path,
        "--loader",
        "maniskill",
        "--model",
        "manipulator",
        "--model",
        "pendulum",
        "--tiers",
        "kinematics,actuated",
    )
    assert code in (0, 1)  # judged, not a usage error
    doc = json.loads((run / "summary.json").read_text())
    models = {m["id"]: m for m in doc["models"]}
    assert doc["loader"] == "maniskill" and {m["status"] for m in models.values()} == {"ok"}
    kinematics = models["manipulator"]["verdicts"]["kinematics"]
    assert kinematics["raw"] == "fail"
    assert _max(kinematics, "orientation") == pytest.approx(np.pi, abs=1e-3)
    actuated = models["pendulum"]["verdicts"]["actuated"]
    assert actuated["raw"] == "skipped" and "actuator" in actuated["notes"][0]
    assert not actuated["worse_than_expected"]
    assert not any("raised" in note for m in models.values() for v in m["verdicts"].values() for note in v["notes"])


def test_a_comparison_puts_both_loaders_side_by_side(tmp_path):
    import json

    code, folder = _run(
        tmp_path, "--compare", "ours,maniskill", "--model", "pendulum", "--tiers", "structure,inertia,actuated"
    )
    assert code == 0  # ours is judged against the manifest: the pendulum passes these
    doc = json.loads((folder / "compare.json").read_text())
    assert doc["loaders"] == ["ours", "maniskill"]
    (pendulum,) = doc["models"]
    cells = pendulum["tiers"]
    assert cells["actuated"]["ours"]["outcome"] == "pass" and cells["actuated"]["maniskill"]["outcome"] == "skipped"
    ms_inertia = cells["inertia"]["maniskill"]
    assert ms_inertia["outcome"] == "fail" and ms_inertia["max"] > ms_inertia["tolerance"]
    assert (folder / "ours" / "summary.md").is_file() and (folder / "maniskill" / "summary.md").is_file()
    row = next(line for line in (folder / "compare.md").read_text().splitlines() if line.startswith("| pendulum"))
    assert row.count(" / ") == 3  # one per tier: both loaders in every cell


def test_the_throughput_bench_times_both_modes_in_one_run(tmp_path, monkeypatch):
    """`nox -s maniskill -- bench`: each robot's physics steps per second under `mujoco_ctrl` and `pd_joint_pos`,
    their ratio, `mujoco_ctrl_tensor`'s where the robot is offered it (and on `physx_cuda`, where CUDA is there, or
    why not), the versions; a robot the Menagerie slice lacks is skipped with its path."""
    from conformance import maniskill_bench
    from conformance.maniskill_bench import TENSOR

    if menagerie_root() is None:
        pytest.skip("Menagerie slice not installed")
    monkeypatch.setitem(maniskill_bench.ROBOTS, "absent", "no_such_robot/robot.xml")
    out = tmp_path / "maniskill_bench.json"
    doc = maniskill_bench.maniskill_bench(out, control_steps=3)
    assert json.loads(out.read_text()) == doc and doc["versions"]["mani-skill"] == mani_skill.__version__
    panda = doc["robots"]["panda"]
    assert panda["sim_freq"] == 500 and all(panda[mode] > 0 for mode in maniskill_bench.MODES)
    assert panda["ratio"] == pytest.approx(panda["mujoco_ctrl"] / panda["pd_joint_pos"])
    assert panda["tensor_ratio"] == pytest.approx(panda[TENSOR] / panda["pd_joint_pos"])  # offered the mode
    assert isinstance(panda["tensor_ops"], int) and panda["tensor_ops"] > 100  # M, c and the rows: hundreds
    if torch.cuda.is_available():  # physx_cuda, GPU_ENVS sub-scenes, both modes on the device
        assert panda["gpu"]["tensor_ratio"] == pytest.approx(panda["gpu"][TENSOR] / panda["gpu"]["pd_joint_pos"])
    else:
        assert "no CUDA device" in panda["gpu"]["skipped"]
    assert "no_such_robot/robot.xml not found" in doc["robots"]["absent"]["skipped"]
