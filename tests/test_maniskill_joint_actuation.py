"""`mujoco_ctrl_tensor`: the joint actuation law (loader/plan/joint_actuation.py) over (env, DoF) tensors in
ManiSkill (loader/maniskill/joint_actuation.py). MuJoCo is the oracle: the law's force is MuJoCo's actuator and
passive force at any state, its step's end velocity is MuJoCo's, and the mode follows MuJoCo stepped with the same
ctrl under PGS and TGS. Needs torch and mani_skill (the `maniskill` extra); the CUDA test skips without a GPU."""

from __future__ import annotations

import re
import warnings
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, corpus_params, suite_path

torch = pytest.importorskip("torch", reason="torch is not installed (the `maniskill` extra)")
pytest.importorskip("mani_skill", reason="mani_skill is not installed (the `maniskill` extra)")

from test_joint_actuation import ACTUATED, DOF_OF_JOINT, SIBLINGS, SPATIAL

from conformance.tiers.maniskill import empty_env
from loader import MJCFLoader
from loader.maniskill import constraint_rows, joint_actuation, register_agent
from loader.maniskill import inertia as inertia_module
from loader.maniskill.free_root import RootRows
from loader.maniskill.inertia import Inertia
from loader.maniskill.joint_actuation import Law, implicit_step, next_activation, start_force
from loader.plan.joint_actuation import OTHER_EQUALITIES, plan_joint_actuation, robot_indices
from loader.plan.rigid_tree import rigid_tree


def _acts(model: mujoco.MjModel, act: np.ndarray) -> np.ndarray:
    """MuJoCo's act (na) per actuator (nu): each actuator with dynamics reads its one activation."""
    out = np.zeros(model.nu)
    has = model.actuator_actadr >= 0
    out[has] = act[model.actuator_actadr[has]]
    return out


def _mujoco_forces(model: mujoco.MjModel, q: np.ndarray, v: np.ndarray, ctrl: np.ndarray, act: np.ndarray):
    """MuJoCo's qfrc_actuator + qfrc_passive at each row's state, activation and ctrl."""
    data, out = mujoco.MjData(model), []
    for row in range(q.shape[0]):
        data.qpos[:], data.qvel[:], data.ctrl[:], data.act[:] = q[row], v[row], ctrl[row], act[row]
        mujoco.mj_forward(model, data)
        out.append(data.qfrc_actuator + data.qfrc_passive)
    return np.array(out)


def _mistaken(name: str, plan) -> None:
    """A small mistake in the plan: the position servo's spring left out, the joint's actuatorfrcrange left out,
    every actuator's kv taken explicitly (MuJoCo's implicit step takes it implicitly), or the tendon's spring left
    out."""
    if name == "no_position_gain":
        plan.bias[1, 0] = 0.0
    elif name == "no_joint_range":
        plan.joint_range[:, 0] = [-np.inf, np.inf]
    elif name == "kv_explicit":
        plan.velocity_gain[:] = 0.0
    elif name == "tendon_unsprung":
        plan.springs.stiffness[:] = 0.0


@pytest.mark.parametrize("mistake", [None, "no_position_gain", "no_joint_range", "tendon_unsprung"])
@pytest.mark.parametrize("integrator", ["implicitfast", "Euler", "implicitfast group off"])
def test_the_law_gives_mujocos_actuator_and_passive_force(integrator, mistake):
    """At 64 random states, activations and ctrls (past ctrlrange, binding forcerange and actuatorfrcrange), the
    law's joint force at the step's start is MuJoCo's actuator and passive force (the fixed tendon's spring in its
    deadband or out of it, and its damper), to float64 rounding, in float64 on the CPU, also with the motor's
    actuator group disabled; each mistake breaks it."""
    xml = ACTUATED.format(integrator=integrator.split()[0])
    if integrator.endswith("group off"):
        xml = xml.replace("<motor ", '<motor group="2" ').replace("<option ", '<option actuatorgroupdisable="2" ')
    model = mujoco.MjModel.from_xml_string(xml)
    plan = plan_joint_actuation(model, DOF_OF_JOINT, model.nv)
    _mistaken(mistake, plan)
    rng = np.random.default_rng(0)
    q, v, ctrl = rng.uniform(-1, 1, (64, 3)), rng.uniform(-3, 3, (64, 3)), rng.uniform(-3, 3, (64, model.nu))
    act = rng.uniform(-1, 1, (64, model.na))
    law = Law(plan, model.opt.timestep, "cpu", torch.float64)
    state = (torch.as_tensor(x) for x in (ctrl, q, v))
    qf = start_force(law, *state, act=torch.as_tensor(np.array([_acts(model, a) for a in act]))).numpy()
    error = np.abs(qf - _mujoco_forces(model, q, v, ctrl, act)).max()
    assert (error < 1e-10) == (mistake is None), error


@pytest.mark.parametrize("integrator", ["implicitfast", "Euler"])
def test_the_activation_steps_as_mujocos(integrator):
    """From 64 random activations and ctrls (past ctrlrange and actrange), one step of the law's activation is
    MuJoCo's `mj_step`'s: the filter by Euler, the exact filter exactly, the integrator held to its actrange. With
    the exact filter stepped by Euler it is not."""
    model = mujoco.MjModel.from_xml_string(ACTUATED.format(integrator=integrator))
    plan = plan_joint_actuation(model, DOF_OF_JOINT, model.nv)
    rng, data = np.random.default_rng(1), mujoco.MjData(model)
    act, ctrl = rng.uniform(-1, 1, (64, model.na)), rng.uniform(-3, 3, (64, model.nu))
    expected = []
    for row in range(64):
        mujoco.mj_resetData(model, data)
        data.act[:], data.ctrl[:] = act[row], ctrl[row]
        mujoco.mj_step(model, data)
        expected.append(_acts(model, data.act))
    law = Law(plan, model.opt.timestep, "cpu", torch.float64)
    before = torch.as_tensor(np.array([_acts(model, a) for a in act]))
    stepped = next_activation(law, torch.as_tensor(ctrl), before).numpy()
    activated = model.actuator_actadr >= 0
    assert np.abs(stepped - np.array(expected))[:, activated].max() < 1e-12
    law.exact[:] = False  # the mistake: filterexact stepped as a filter
    assert np.abs(next_activation(law, torch.as_tensor(ctrl), before).numpy() - np.array(expected)).max() > 1e-6


def _follow(uid: str, model: mujoco.MjModel, tgs: bool = False, joints: slice = slice(None)) -> float:
    """The largest |ManiSkill - MuJoCo| position of `joints` over 0.5 s of `mujoco_ctrl_tensor` (a 0.3 sine on
    every ctrl around the keyframe's), ten physics steps per control step, MuJoCo stepped with the same ctrl."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    env = empty_env(uid, "mujoco_ctrl_tensor", 500, 50, None if tgs else {"enable_tgs": False})
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent.robot
        robot.set_qpos(np.asarray(data.qpos, np.float32)[None])
        robot.set_qvel(np.zeros((1, model.nv), np.float32))
        worst = 0.0
        for step in range(25):
            ctrl = (model.key_ctrl[0] + 0.3 * np.sin(2 * np.pi * step / 25)).astype(np.float32)
            env.step(ctrl)
            data.ctrl[:] = ctrl
            for _ in range(10):
                mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(robot.get_qpos()[0].numpy() - data.qpos)[joints].max()))
    finally:
        env.close()
    return worst


# rad, the largest |ManiSkill - MuJoCo| joint position of the stiff servo arm over 0.5 s under mujoco_ctrl_tensor
# (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0, torch 2.13.0): PGS 3.5e-7, TGS 1.6e-5 (TGS's position update over
# its substeps; `mujoco_ctrl` measures the same on this arm); with the kv taken explicitly the arm flies off (2e2).
# Under PGS, with every body compensated fully (gravcomp 1): 5.0e-7 (the links left weighing: 6.8e-4); each servo
# behind a 10 ms filter: 3.1e-7 (the activations never stepped: 2.9)
TENSOR_FOLLOW_TOLERANCE = {"pgs": 1e-5, "tgs": 1e-4}
# rad, the Menagerie panda's arm joints the same way: its servos saturate (forcerange) through most of the sine, where
# MuJoCo's force has no implicit term. Measured 2.6e-5 under PGS (its fingers' equality and limits, which the law leaves
# to PhysX, stay in); with the clamps' kv still taken implicitly 0.13
SATURATED_TOLERANCE = 2e-4
# relative, the law's end velocity against MuJoCo's step (no constraint rows) at 32 random states: measured 2.0e-6
# (PhysX's float32 masses and frames in M and c); with joint limit rows 3.5e-7, with frictionloss rows too 4.0e-7,
# with joint couplings 8.8e-7, with tendon couplings 1.1e-7, with tendon limits and frictionloss 1.4e-6, with a connect
# 9.6e-7, with a weld 5.5e-7, with either on a floating base 9.4e-7 (joints and root), with spatial tendons 8.5e-6;
# each mistake misses by 5e-4 or more
STEP_TOLERANCE = 1e-4


@pytest.mark.parametrize("mistake", [None, "kv_explicit"])
@pytest.mark.parametrize("solver", ["pgs", "tgs"])
def test_mujoco_ctrl_tensor_follows_mujoco_on_the_cpu_backend(solver, mistake):
    """The stiff servo arm (kp 5000, kv 200 on light links) in `Empty-v1` under `mujoco_ctrl_tensor` follows MuJoCo
    under PGS and under ManiSkill's default, TGS: the law writes the joint force of MuJoCo's step, which either
    solver steps as MuJoCo does. With the servos' kv taken explicitly, it does not."""
    path = FIXTURES / "folding_servo_arm.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_arm_{solver}_{mistake}", override=True)
    _mistaken(mistake, agent.joint_actuation)
    worst = _follow(agent.uid, model, tgs=solver == "tgs")
    assert (worst < TENSOR_FOLLOW_TOLERANCE[solver]) == (mistake is None), worst


def _ignore_clamps(monkeypatch) -> None:
    """The mistake of taking a clamped actuator's kv implicitly all the same: the law sees no clamp bind."""
    actuation = joint_actuation._actuation

    def unclamped(*args):
        actuated, clamped = actuation(*args)
        return actuated, torch.zeros_like(clamped)

    monkeypatch.setattr(joint_actuation, "_actuation", unclamped)


def _loaded_law(xml: str | Path):
    """A model loaded from `xml` (or the file at that path), its law planned over its one articulation and its
    tree's M and c."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(str(xml) if isinstance(xml, Path) else mujoco.MjSpec.from_string(xml))
    articulation = result.articulations[0]
    dofs, links = robot_indices(result.mapping)
    plan = plan_joint_actuation(result.model, dofs, articulation.dof, links)
    inertia = Inertia(rigid_tree(articulation), result.model.opt.gravity, plan.weightless, "cpu")
    return result, dofs, plan, inertia


@pytest.mark.parametrize("mistake", [None, "kv_explicit", "clamps_ignored", "cross_terms_everywhere"])
@pytest.mark.parametrize("fixture", ["chain", "siblings"])
def test_the_laws_step_is_mujocos(monkeypatch, fixture, mistake):
    """At 32 random states, ctrls (past ctrlrange, binding forcerange and actuatorfrcrange) and activations, the
    law's end velocity is MuJoCo's step's (its constraint rows off), under implicitfast: the chain of every actuator
    kind and the gripper's fingers on one tendon servo. Each mistake misses one of them: the kv taken explicitly, a
    binding clamp's kv taken implicitly, a tendon's cross terms kept across branches (the fingers)."""
    xml = (ACTUATED if fixture == "chain" else SIBLINGS).format(integrator="implicitfast")
    result, dofs, plan, inertia = _loaded_law(xml)
    model = result.model
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    _mistaken(mistake, plan)
    if mistake == "cross_terms_everywhere":
        plan.chained[:] = True
    law = Law(plan, model.opt.timestep, "cpu", torch.float64)
    if mistake == "clamps_ignored":
        _ignore_clamps(monkeypatch)
    joints = sorted(dofs, key=dofs.get)
    qpos, qvel = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    root = result.articulations[0].get_root_pose()
    pose = torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None]
    data, rng, worst = mujoco.MjData(model), np.random.default_rng(0), 0.0
    low, high = np.where(model.actuator_ctrllimited[:, None], model.actuator_ctrlrange, [-3.0, 3.0]).T
    for _ in range(32):
        mujoco.mj_resetData(model, data)
        data.qpos[qpos], data.qvel[qvel] = rng.uniform(-0.05, 0.05, len(joints)), rng.uniform(-2, 2, len(joints))
        data.ctrl[:] = rng.uniform(low - 0.5 * (high - low), high + 0.5 * (high - low))
        data.act[:] = rng.uniform(-0.5, 0.5, model.na)
        q, v = torch.tensor(data.qpos[qpos])[None], torch.tensor(data.qvel[qvel])[None]
        act = torch.tensor(_acts(model, data.act))[None]
        end = implicit_step(law, inertia, torch.tensor(data.ctrl)[None], q, v, pose, None, act)[1][0].numpy()
        mujoco.mj_step(model, data)
        worst = max(worst, float(np.abs(end - data.qvel[qvel]).max() / max(1.0, np.abs(data.qvel[qvel]).max())))
    wrong = {
        "kv_explicit": True,
        "clamps_ignored": fixture == "chain",
        "cross_terms_everywhere": fixture == "siblings",
    }.get(mistake, False)
    assert (worst > STEP_TOLERANCE) == wrong, worst


def test_a_robot_outside_the_law_is_not_offered_the_mode(tmp_path):
    """The law's scope decides the mode: a robot pulled by a spatial tendon gets no `mujoco_ctrl_tensor`, and its
    agent keeps why; the servo arm gets it."""
    path = tmp_path / "pulled.xml"
    path.write_text(SPATIAL)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pulled = register_agent(path, "tensor_pulled", override=True)
        arm = register_agent(FIXTURES / "folding_servo_arm.xml", "tensor_offered", override=True)
    assert "spatial tendon" in pulled.joint_actuation
    for agent, offered in ((pulled, False), (arm, True)):
        env = empty_env(agent.uid, "mujoco_ctrl", 500, 50)
        try:
            assert ("mujoco_ctrl_tensor" in env.unwrapped.agent.supported_control_modes) == offered
        finally:
            env.close()


def test_a_robot_whose_tree_the_law_cannot_read_keeps_the_reason(monkeypatch):
    """A joint type the rigid-body tree does not take (here: slides, struck from it) keeps the robot out of the mode,
    its agent saying which joint; the robot registers all the same."""
    from loader.plan import rigid_tree as tree

    monkeypatch.setattr(tree, "KINDS", {k: v for k, v in tree.KINDS.items() if k != "prismatic"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(suite_path("cartpole"), "tensor_untreed", override=True)
    assert "prismatic" in agent.joint_actuation and agent.rigid_tree is None


def _gpu_env(uid: str, sim_freq: int, control_freq: int, scene_config: dict | None = None):
    """`Empty-v1` with 4 sub-scenes on `physx_cuda` under `mujoco_ctrl_tensor`, without rendering."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return empty_env(
            uid, "mujoco_ctrl_tensor", sim_freq, control_freq, scene_config, backend="physx_cuda", num_envs=4
        )


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA (ManiSkill's physx_cuda backend)")
@pytest.mark.parametrize("fixture", ["folding_servo_arm.xml", "wrapped_tendons.xml"])
def test_mujoco_ctrl_tensor_steps_every_sub_scene_on_the_gpu(fixture):
    """On `physx_cuda` with 4 sub-scenes, the mode's `qf` on the device is the law's for each sub-scene's own state
    and its drives aim at the sub-scene's end velocity (the same code as on the CPU, one launch per operation for all
    of them): the servo arm, and the arm pulled by spatial tendons over a sphere and a cylinder."""
    path = FIXTURES / fixture
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_gpu_{path.stem}", override=True)
    env = _gpu_env(agent.uid, 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        unwrapped = env.unwrapped
        ctrl = torch.linspace(-0.5, 0.5, 4 * 3, device=unwrapped.device).reshape(4, 3)
        env.step(ctrl)
        robot, controller = unwrapped.agent.robot, unwrapped.agent.controller.controllers["ctrl"]
        unwrapped.scene.px.gpu_fetch_articulation_qpos()
        unwrapped.scene.px.gpu_fetch_articulation_qvel()
        q, v, pose, velocity = controller.state()
        act = controller.act.clone()
        controller.before_simulation_step()
        step = implicit_step(controller.law, controller.inertia, controller.ctrl, q, v, pose, velocity, act)
        assert torch.allclose(robot.get_qf(), step.qf.float())
        assert torch.allclose(robot.get_drive_velocities(), step.end.float())  # ManiSkill's own reader
        assert not torch.allclose(step.qf[0], step.qf[1])  # each sub-scene its own ctrl and state
    finally:
        env.close()


@pytest.mark.parametrize("mistake", [None, "weighing"])
def test_a_compensated_arm_follows_mujoco_with_its_links_weightless(tmp_path, mistake):
    """The stiff servo arm with every body compensated fully (gravcomp 1) follows MuJoCo under PGS: its links weigh
    nothing in PhysX, as MuJoCo's gravity and compensation cancel at their centres of mass. With the links left
    weighing, gravity sags the arm past the tolerance."""
    xml = (FIXTURES / "folding_servo_arm.xml").read_text().replace('<body name="', '<body gravcomp="1" name="')
    path = tmp_path / "compensated_arm.xml"
    path.write_text(xml)
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_compensated_{mistake}", override=True)
    assert len(agent.joint_actuation.weightless) == 3
    if mistake:
        agent.joint_actuation.weightless = []
    worst = _follow(agent.uid, model)
    assert (worst < TENSOR_FOLLOW_TOLERANCE["pgs"]) == (mistake is None), worst


@pytest.mark.parametrize("mistake", [None, "clamps_ignored"])
def test_a_saturated_arm_follows_mujoco(monkeypatch, mistake):
    """The panda's arm under a sine that saturates its servos follows MuJoCo within `SATURATED_TOLERANCE`: where a
    clamp binds, MuJoCo's force has no implicit term, and the law's step leaves it out. With the clamps' kv taken
    implicitly all the same, the arm misses."""
    from support.corpus import menagerie_root

    root = menagerie_root()
    if root is None:
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    path = root / "franka_emika_panda/panda.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_panda_{mistake}", override=True)
    if mistake:
        _ignore_clamps(monkeypatch)
    worst = _follow(agent.uid, model, joints=slice(0, 7))
    assert (worst < SATURATED_TOLERANCE) == (mistake is None), worst


def _planned(path):
    """The corpus model loaded, and its law planned over its first articulation as `register_agent` plans it."""
    from loader import MJCFLoader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(str(path))
    dofs, _ = robot_indices(result.mapping)
    ndof = result.articulations[0].dof if result.articulations else 0
    return result.model, dofs, plan_joint_actuation(result.model, dofs, ndof)


def _worst_law_error(model: mujoco.MjModel, dofs: dict, plan) -> float:
    """The largest relative difference, over 16 random states and ctrls (past ctrlrange), between the law's force
    at the step's start and MuJoCo's actuator and passive force less what the
    law leaves to the build (gravity compensation, weightless links) or lists as not carried (fluid)."""
    rng, data = np.random.default_rng(0), mujoco.MjData(model)
    law = Law(plan, model.opt.timestep, "cpu", torch.float64)
    joints = list(dofs)
    qpos, qvel, robot = model.jnt_qposadr[joints], model.jnt_dofadr[joints], [dofs[j] for j in joints]
    low, high = model.actuator_ctrlrange.T
    worst = 0.0
    for _ in range(16):
        mujoco.mj_resetData(model, data)
        data.qpos[qpos] += rng.uniform(-0.3, 0.3, len(joints))
        data.qvel[qvel] = rng.uniform(-1, 1, len(joints))
        data.ctrl[:] = rng.uniform(low - 0.2 * (high - low), high + 0.2 * (high - low))
        mujoco.mj_forward(model, data)
        expected = (data.qfrc_actuator + data.qfrc_passive - data.qfrc_gravcomp - data.qfrc_fluid)[qvel]
        q, v = np.zeros((1, plan.ndof)), np.zeros((1, plan.ndof))
        q[0, robot], v[0, robot] = data.qpos[qpos], data.qvel[qvel]
        force = start_force(law, torch.as_tensor(data.ctrl[None].copy()), torch.as_tensor(q), torch.as_tensor(v))
        got = force.numpy()[0, robot]
        worst = max(worst, float(np.abs(got - expected).max() / max(1.0, np.abs(expected).max())))
    return worst


@pytest.mark.parametrize("path", corpus_params())
def test_the_law_is_mujocos_on_every_corpus_robot_it_takes(path):
    """Robot by robot over the default corpus: where the law takes the model, its force is MuJoCo's to float64
    rounding (`_worst_law_error`), the fish's fin tendon spring included; where it does not, it says why in words."""
    model, dofs, plan = _planned(path)
    if not model.nu or not dofs:
        pytest.skip("no actuator, or no hinge or slide: nothing for the law")
    if isinstance(plan, str):
        assert plan.startswith("actuator '"), plan  # names the actuator, and why
        return
    assert _worst_law_error(model, dofs, plan) < 1e-10


def test_the_corpus_check_catches_a_gain_a_thousandth_off():
    """The robot-by-robot check is not blind: the cheetah's law with every actuator's gain 0.1 % off misses it."""
    model, dofs, plan = _planned(suite_path("cheetah"))
    plan.gain = plan.gain * 1.001
    assert _worst_law_error(model, dofs, plan) > 1e-10


def _filtered_arm(tmp_path, uid: str):
    """The stiff servo arm with each servo behind a 10 ms filter: (its model, its registered agent)."""
    servo = re.compile(r'<position joint="(\w+)" kp="5000" kv="200"/>')
    filtered = r'<general joint="\1" dyntype="filter" dynprm="0.01" gainprm="5000" biastype="affine" '
    xml = servo.sub(filtered + r'biasprm="0 -5000 -200"/>', (FIXTURES / "folding_servo_arm.xml").read_text())
    path = tmp_path / "filtered_arm.xml"
    path.write_text(xml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, uid, override=True)
    return mujoco.MjModel.from_xml_path(str(path)), agent


def test_a_reset_of_the_one_sub_scene_restarts_its_activations(tmp_path):
    """MuJoCo's reset zeroes act: on the CPU backend's one sub-scene, `env.reset` restarts the activations the law
    stepped, as a mode switch does."""
    model, agent = _filtered_arm(tmp_path, "tensor_filtered_reset")
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        env.step(np.full(model.nu, 0.5, np.float32))
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        assert float(controller.act.abs().min()) > 0.1  # ten steps of a 10 ms filter toward 0.5
        env.reset(seed=1)
        assert float(controller.act.abs().max()) == 0.0
    finally:
        env.close()


@pytest.mark.parametrize("mistake", [None, "mark_ignored"])
def test_a_partial_reset_restarts_only_its_envs(tmp_path, mistake):
    """An `env.reset` of no env (`env_idx` empty: ManiSkill marks none of its sub-scenes) leaves the one env's
    activations and ctrl as they were; a reset of every env restarts them. Mutation: the agent's mark not handed to
    the controller, which then resets every env."""
    from loader.maniskill.agent import MJCFAgent

    model, agent = _filtered_arm(tmp_path, f"tensor_partial_{mistake}")
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        if mistake:
            env.unwrapped.agent.reset = lambda init_qpos=None: super(MJCFAgent, env.unwrapped.agent).reset(init_qpos)
        env.step(np.full(model.nu, 0.5, np.float32))
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        act, ctrl = controller.act.clone(), controller.ctrl.clone()
        assert float(act.abs().min()) > 0.1
        env.reset(seed=1, options={"env_idx": torch.tensor([], dtype=torch.long)})
        kept = torch.equal(controller.act, act) and torch.equal(controller.ctrl, ctrl)
        assert kept == (mistake is None)
        env.reset(seed=2)
        assert float(controller.act.abs().max()) == 0.0
    finally:
        env.close()


@pytest.mark.parametrize("mistake", [None, "mark_ignored"])
def test_a_reset_env_restarts_while_the_others_run_on(tmp_path, mistake):
    """Two envs' rows (as on the GPU backend), the first reset: its ctrl and activations restart at zero, while the
    second keeps its own. Mutation: the mark dropped, so that every env restarts."""
    _, agent = _filtered_arm(tmp_path, f"tensor_rows_{mistake}")
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        rows = torch.tensor([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], dtype=torch.float64)
        controller.ctrl, controller.act = rows.clone(), rows.clone()
        controller.resetting = None if mistake else torch.tensor([True, False])
        controller.reset()
        assert controller.ctrl[0].abs().max() == 0.0 and controller.act[0].abs().max() == 0.0
        kept = torch.equal(controller.ctrl[1], rows[1]) and torch.equal(controller.act[1], rows[1])
        assert kept == (mistake is None)
    finally:
        env.close()


@pytest.mark.parametrize("mistake", [None, "activation_held"])
def test_a_filtered_arm_follows_mujoco_with_its_activations_stepped(tmp_path, monkeypatch, mistake):
    """The stiff servo arm with each servo behind a first-order filter (MuJoCo's dyntype filter, 10 ms) follows
    MuJoCo under PGS: the law steps each env's activations as MuJoCo does and the servos multiply them. With the
    activations never stepped, the servos push nothing and the arm falls."""
    from loader.maniskill import joint_actuation

    model, agent = _filtered_arm(tmp_path, f"tensor_filtered_{mistake}")
    assert model.na == 3
    if mistake:
        monkeypatch.setattr(joint_actuation, "next_activation", lambda law, ctrl, act: act)
    worst = _follow(agent.uid, model)
    assert (worst < TENSOR_FOLLOW_TOLERANCE["pgs"]) == (mistake is None), worst


SWINGING_LEGS = """
<mujoco model="swinging_legs">
  <option timestep="0.01"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="torso" pos="0 0 {height}">
      <freejoint name="root"/>
      <geom type="sphere" size="0.2" mass="2" contype="{contype}" conaffinity="{contype}"/>
      <body name="left" pos="0.2 0 0">
        <joint name="left" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.05" mass="0.5"/>
      </body>
      <body name="right" pos="-0.2 0 0">
        <joint name="right" axis="0 0.3 1"/>
        <geom type="capsule" fromto="0 0 0 -0.4 0.1 0" size="0.05" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="left" gear="3"/><motor joint="right" gear="2"/></actuator>
</mujoco>
"""
# m or rad, m/s or rad/s: the largest |ManiSkill - MuJoCo| of the swinging legs' qpos and qvel (the free joint's
# among them) over 0.5 s under mujoco_ctrl_tensor and TGS (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0, torch
# 2.13.0): measured 7.2e-6; with the root left to PhysX's step 7.5e-2
ROOT_TOLERANCE = 1e-4


def _swinging_legs(tmp_path, uid: str, contype: int = 0, height: float = 2.0):
    path = tmp_path / f"{uid}.xml"
    path.write_text(SWINGING_LEGS.format(contype=contype, height=height))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, uid, override=True)
    return mujoco.MjModel.from_xml_path(str(path)), agent


@pytest.mark.parametrize("mistake", [None, "root_left_to_physx"])
def test_a_floating_robot_keeps_mujocos_root(tmp_path, monkeypatch, mistake):
    """A floating body swinging two legs on their motors, contact-free, follows MuJoCo root and joints under TGS:
    after each physics step the root takes the velocity MuJoCo's step on the free joint's rows gives and the pose its
    position update gives. Left to PhysX's step, which conserves the tree's momentum, the root parts from MuJoCo's."""
    from loader.maniskill.joint_actuation import JointActuationController

    model, agent = _swinging_legs(tmp_path, f"tensor_legs_{mistake}")
    if mistake == "root_left_to_physx":
        monkeypatch.setattr(JointActuationController, "touched", lambda self: torch.ones(1, dtype=torch.bool))
    data = mujoco.MjData(model)
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 100, 100)
    try:
        env.reset(seed=0)
        (result,) = env.unwrapped.agent.results
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        result.set_state(data.qpos, data.qvel)
        worst = 0.0
        for step in range(50):
            data.ctrl[:] = np.float32([np.sin(0.5 * step), np.cos(0.3 * step)])
            env.step(data.ctrl.astype(np.float32))
            mujoco.mj_step(model, data)
            controller.settle()
            qpos, qvel = result.get_state()
            worst = max(worst, float(np.abs(qpos - data.qpos).max()), float(np.abs(qvel - data.qvel).max()))
    finally:
        env.close()
    assert (worst < ROOT_TOLERANCE) == (mistake is None), worst


@pytest.mark.parametrize("mistake", [None, "blind"])
@pytest.mark.parametrize("case", ["contact", "state_set"])
def test_the_root_stays_physxs_where_the_law_cannot_know_its_step(tmp_path, monkeypatch, case, mistake):
    """The root keeps PhysX's end of a step where MuJoCo's step on its rows would miss a force: where the robot rests
    on the ground (the contact's impulse is not the law's; under PGS, whose position update leaves the joints where
    their velocities take them, so that only the contact check sees it), or where its state was set from outside
    after the step. Mutation: the check blind to it (no contact seen; every env taken as stepped), and the root is
    rewritten."""
    from loader.maniskill import free_root
    from loader.maniskill.joint_actuation import JointActuationController

    contact = case == "contact"
    _, agent = _swinging_legs(tmp_path, f"tensor_kept_{case}_{mistake}", 1 if contact else 0, 0.2)
    if mistake == "blind" and contact:
        monkeypatch.setattr(JointActuationController, "touched", lambda self: torch.zeros(1, dtype=torch.bool))
    elif mistake == "blind":
        monkeypatch.setattr(free_root.RootRows, "stepped", lambda self, q, v: self.pending)
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 100, 100, {"enable_tgs": False} if contact else None)
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent.robot
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        for _ in range(1 if contact else 3):  # from rest on the ground, the first step's joints step as PhysX's do
            env.step(np.float32([1.0, -1.0]))
        if not contact:
            robot.set_qpos(robot.get_qpos() + 0.1)
        before = torch.cat((robot.root_pose.raw_pose, robot.root_linear_velocity), -1).clone()
        controller.settle()
        after = torch.cat((robot.root_pose.raw_pose, robot.root_linear_velocity), -1)
    finally:
        env.close()
    assert torch.equal(before, after) == (mistake is None), (before - after).abs().max()


@pytest.mark.parametrize("mistake", [None, "pgs_position_update"])
def test_every_contact_free_tgs_step_of_a_damped_dog_is_settled(monkeypatch, mistake):
    """dm_control's dog in `Empty-v1` under TGS, without gravity, contact-free, under a sine on every ctrl: its light
    limbs under heavy damping (the elbow's 0.3 N m s on 0.17 kg) stray, within TGS's substeps, from where timestep
    times their end velocity takes them, by more than float32's rounding. Every step is still taken as PhysX's step,
    and its root settled. Mutation: PGS's position update demanded (the joints at timestep x end velocity, to float32),
    and most steps keep PhysX's root."""
    from mani_skill.utils.structs.pose import Pose

    from loader.maniskill import free_root

    path = suite_path("humanoid").parents[1] / "locomotion/walkers/assets/dog_v2/dog.xml"
    stepped = free_root.RootRows.stepped
    if mistake:

        def stepped(self, q, v):  # the joints exactly at timestep x end velocity, to float32
            strayed = torch.abs(q - self.q0 - self.timestep * v).amax(-1)
            return self.pending & (strayed <= 1e-6 * (1 + q.abs().amax(-1)))

    taken = []
    monkeypatch.setattr(
        free_root.RootRows, "stepped", lambda self, q, v: taken.append(stepped(self, q, v)) or taken[-1]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_dog_{mistake}", override=True)
    low, high = np.array(agent.ctrl_low), np.array(agent.ctrl_high)
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 200, 200, {"gravity": [0.0, 0.0, 0.0]})
    try:
        env.reset(seed=0)
        robot = env.unwrapped.agent.robot
        raised = robot.root_pose.raw_pose.clone()
        raised[:, 2] += 3.0  # clear of the ground
        robot.set_root_pose(Pose.create(raised))
        for t in range(40):
            env.step(
                (0.5 * (low + high) + 0.4 * (high - low) * np.sin(0.3 * t + np.arange(low.size))).astype(np.float32)
            )
        assert not bool(env.unwrapped.agent.controller.controllers["ctrl"].touched().any())
    finally:
        env.close()
    settled = int(torch.cat(taken).sum())
    assert (settled == len(taken) == 39) == (mistake is None), (settled, len(taken))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA (ManiSkill's physx_cuda backend)")
def test_every_sub_scenes_floating_root_keeps_mujocos_on_the_gpu(tmp_path):
    """On `physx_cuda` with 4 sub-scenes, each under its own ctrl, the swinging legs' root and joints follow MuJoCo
    stepped with that sub-scene's ctrl, within `ROOT_TOLERANCE`: the root rows, the contact query and the root's write
    on the device."""

    from loader.maniskill.free_root import free_velocity

    model, agent = _swinging_legs(tmp_path, "tensor_legs_gpu")
    env = _gpu_env(agent.uid, 100, 100)
    datas = [mujoco.MjData(model) for _ in range(4)]
    try:
        env.reset(seed=0)
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        q, _, pose, _ = controller.state()
        for data, start, root in zip(datas, q.cpu().numpy(), pose.cpu().numpy()):
            data.qpos[:7], data.qpos[7:] = root, start  # each sub-scene's start, as ManiSkill placed it
        worst = 0.0
        for step in range(50):
            ctrl = np.float32([[np.sin(0.5 * step + k), np.cos(0.3 * step - k)] for k in range(4)])
            env.step(torch.as_tensor(ctrl, device=env.unwrapped.device))
            controller.settle()
            q, v, pose, velocity = controller.state()
            free = free_velocity(controller.inertia, pose, velocity)
            ours = torch.cat((pose, q), -1).cpu().numpy(), torch.cat((free, v), -1).cpu().numpy()
            for k, data in enumerate(datas):
                data.ctrl[:] = ctrl[k]
                mujoco.mj_step(model, data)
                worst = max(
                    worst, float(np.abs(ours[0][k] - data.qpos).max()), float(np.abs(ours[1][k] - data.qvel).max())
                )
    finally:
        env.close()
    assert worst < ROOT_TOLERANCE, worst


LIMITED = """
<mujoco model="limited_chain">
  <option timestep="0.01"><flag contact="disable"/></option>
  <default><joint limited="true" damping="0.1"/></default>
  <worldbody>
    <body>
      <joint name="a" axis="0 1 0" range="-0.5 0.5" solreflimit="0.03 0.8" solimplimit="0.8 0.97 0.01 0.3 3"
             margin="0.02"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body pos="0.3 0 0">
        <joint name="b" axis="0 1 0" range="-1 0.2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body pos="0.3 0 0">
          <joint name="c" type="slide" axis="1 0 0" range="-0.05 0.05" solreflimit="-2000 -30"/>
          <geom type="box" size="0.05 0.05 0.05"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="a" gear="5"/><motor joint="b" gear="3"/><motor joint="c" gear="10"/></actuator>
</mujoco>
"""


def _worst_rows_step(result, dofs, plan, inertia, slow: float) -> float:
    """The largest relative |law - MuJoCo| end velocity over 32 random states about and past the ranges' ends and
    ctrls (a share `slow` of them nearly still and barely pushed, where frictionloss holds a joint), MuJoCo's rows
    on; on a floating robot (its free joint MuJoCo's first) at random root poses and velocities, the root's end
    velocity too (`RootRows` on the step's M, c and f)."""
    model = result.model
    law = Law(plan, model.opt.timestep, "cpu", torch.float64)
    joints = sorted(dofs, key=dofs.get)
    qpos, qvel = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    root = result.articulations[0].get_root_pose()
    pose, root_velocity = torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None], None
    compared = list(qvel) + list(range(6)) * inertia.floating
    data, rng, worst = mujoco.MjData(model), np.random.default_rng(0), 0.0
    for sample in range(32):
        mujoco.mj_resetData(model, data)
        push = 0.01 if sample < slow * 32 else 1.0
        data.qpos[qpos] = rng.uniform(model.jnt_range[joints, 0] - 0.06, model.jnt_range[joints, 1] + 0.06)
        data.qvel[qvel] = rng.uniform(-2.0 * push, 2.0 * push, len(joints))
        data.ctrl[:] = rng.uniform(-push, push, model.nu)
        if inertia.floating:
            assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
            turn = rng.normal(size=4)
            data.qpos[:7], data.qvel[:6] = (
                np.r_[rng.uniform(-1, 1, 3), turn / np.linalg.norm(turn)],
                rng.uniform(-1, 1, 6),
            )
            pose, root_velocity = torch.tensor(data.qpos[None, :7]), torch.tensor(data.qvel[None, :6])
        q, v = torch.tensor(data.qpos[qpos])[None], torch.tensor(data.qvel[qvel])[None]
        step = implicit_step(law, inertia, torch.tensor(data.ctrl)[None], q, v, pose, root_velocity)
        end = step.end[0].numpy()
        if inertia.floating:
            rows = step.root_rows(q, v, pose, root_velocity, law.timestep)
            end = np.r_[end, rows.end(step.end)[1][0].numpy()]
        mujoco.mj_step(model, data)
        expected = data.qvel[compared]
        worst = max(worst, float(np.abs(end - expected).max() / max(1.0, np.abs(expected).max())))
    return worst


@pytest.mark.parametrize("mistake", [None, "no_margin", "impedance_flat", "two_passes"])
def test_the_laws_limit_rows_are_mujocos(monkeypatch, mistake):
    """At 32 random states about and past the ranges' ends (a margin, a solimp sigmoid, the direct solref form on the
    slide), the law's end velocity is MuJoCo's step's with its limit rows: measured 3.5e-7 relative (`STEP_TOLERANCE`).
    Each mistake misses: the margin left out (2.6), the impedance taken as dmax everywhere (0.23), the rows' zones
    taken again only twice (0.41; three passes settle it here)."""
    result, dofs, plan, inertia = _loaded_law(LIMITED)
    if mistake == "no_margin":
        plan.limits.margin[:] = 0.0
    elif mistake == "impedance_flat":
        plan.limits.solimp[0] = plan.limits.solimp[1]
    elif mistake == "two_passes":
        monkeypatch.setattr(constraint_rows, "ROW_PASSES", 2)
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


FRICTIONAL = LIMITED.replace(
    'margin="0.02"/>',
    'margin="0.02" frictionloss="0.3" solreffriction="0.03 0.8" solimpfriction="0.7 0.95 0.01 0.5 2"/>',
).replace(
    '<joint name="b" axis="0 1 0" range="-1 0.2"/>', '<joint name="b" axis="0 1 0" range="-1 0.2" frictionloss="0.05"/>'
)
FRICTIONAL = FRICTIONAL.replace(
    'solreflimit="-2000 -30"/>', 'solreflimit="-2000 -30" frictionloss="2" solreffriction="-100 -30"/>'
)


@pytest.mark.parametrize("mistake", [None, "unbounded", "weight_at_dmax"])
def test_the_laws_frictionloss_rows_are_mujocos(mistake):
    """The limited chain with frictionloss on every joint (its own solreffriction and solimpfriction on the hinge, the
    direct solref form on the slide), at 32 random states, half of them nearly still and barely pushed: the law's end
    velocity is MuJoCo's step's with its limit and frictionloss rows, measured 4.0e-7 relative (`STEP_TOLERANCE`;
    four passes settle it, five where every state is still). Each mistake misses: frictionloss's force left unbounded
    (a damper: 0.66), its weight taken at solimp's dmax rather than at zero violation (5.1e-4)."""
    result, dofs, plan, inertia = _loaded_law(FRICTIONAL)
    assert np.count_nonzero(plan.friction.loss) == 3
    if mistake == "unbounded":
        plan.friction.loss[:] = np.inf
    elif mistake == "weight_at_dmax":
        plan.friction.weight *= [(0.95 / 0.05) / (0.7 / 0.3), (0.95 / 0.05) / (0.9 / 0.1), (0.95 / 0.05) / (0.9 / 0.1)]
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.5)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


def _chain(name: str, a: str, b: str, c: str, rows: str) -> str:
    """A chain of two hinges and a slide, each motor-driven, for the law's row tests: each joint's further attributes,
    and the rows' sections (tendons, equalities)."""
    return f"""
<mujoco model="{name}">
  <compiler angle="radian"/>
  <option timestep="0.005"><flag contact="disable"/></option>
  <worldbody>
    <body>
      <joint name="a" axis="0 1 0" {a}/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body pos="0.3 0 0">
        <joint name="b" axis="0 1 0" {b}/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body pos="0.3 0 0">
          <joint name="c" type="slide" axis="1 0 0" {c}/>
          <geom type="box" size="0.05 0.05 0.05"/>
        </body>
      </body>
    </body>
  </worldbody>
  {rows}
  <actuator><motor joint="a" gear="5"/><motor joint="b" gear="3"/><motor joint="c" gear="10"/></actuator>
</mujoco>
"""


COUPLED = _chain(
    "coupled_chain",
    'ref="0.1" damping="0.05"',
    'range="-0.3 0.3" limited="true"',
    "",
    """<equality>
    <joint joint1="c" joint2="a" polycoef="0.01 0.5 0.2 0.3 0.1" solref="0.01 0.9" solimp="0.9 0.99 0.002 0.5 2"/>
    <joint joint1="b" polycoef="0.05 0 0 0 0"/>
  </equality>""",
)


@pytest.mark.parametrize("mistake", [None, "linear_term_dropped", "first_joint_weight"])
def test_the_laws_joint_couplings_are_mujocos(mistake):
    """A chain whose slide follows a quartic of the first hinge and whose second hinge is held at 0.05 rad (MuJoCo's
    joint equalities, one with its own solref and solimp), the second hinge limited too: at 32 random states the
    law's end velocity is MuJoCo's step's with its equality rows, measured 8.8e-7 relative (`STEP_TOLERANCE`). Each
    mistake misses: the polynomial's linear term dropped (3.1), a row's diagApprox the first joint's invweight0 alone
    (0.23)."""
    result, dofs, plan, inertia = _loaded_law(COUPLED)
    assert plan.couplings.first.shape[0] == 2
    assert OTHER_EQUALITIES not in plan.not_carried
    if mistake == "linear_term_dropped":
        plan.couplings.poly[1] = 0.0
    elif mistake == "first_joint_weight":
        plan.couplings.diag_approx[0] = result.model.dof_invweight0[2]
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


TENDON_COUPLED = _chain(
    "tendon_coupled_chain",
    'ref="0.2"',
    'ref="-0.1" damping="0.05"',
    'ref="0.05"',
    """<tendon>
    <fixed name="ab"><joint joint="a" coef="1"/><joint joint="b" coef="0.5"/></fixed>
    <fixed name="cb"><joint joint="c" coef="2"/><joint joint="b" coef="-1"/></fixed>
  </tendon>
  <equality>
    <tendon tendon1="ab" tendon2="cb" polycoef="0.02 0.6 0.2 0 0" solref="0.01 0.9" solimp="0.9 0.99 0.002 0.5 2"/>
  </equality>""",
)


@pytest.mark.parametrize("mistake", [None, "origin_at_zero", "first_tendon_weight"])
def test_the_laws_tendon_couplings_are_mujocos(mistake):
    """A chain whose fixed tendon over two hinges follows a quadratic of another over the slide and a hinge (MuJoCo's
    tendon equality, its own solref and solimp; every joint authored with a ref, so each tendon's length at qpos0 is
    not zero): at 32 random states the law's end velocity is MuJoCo's step's with its equality row, measured 1.1e-7
    relative (`STEP_TOLERANCE`). Each mistake misses: the lengths' origins taken at zero rather than at qpos0 (3.5), the
    row's diagApprox the first tendon's invweight0 alone (8.5e-2)."""
    result, dofs, plan, inertia = _loaded_law(TENDON_COUPLED)
    assert plan.couplings.first.shape[0] == 1 and not plan.not_carried
    if mistake == "origin_at_zero":
        plan.couplings.origin[:] = 0.0
    elif mistake == "first_tendon_weight":
        plan.couplings.diag_approx[0] = result.model.tendon_invweight0[0]
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


TENDON_ROWS = _chain(
    "tendon_limited_chain",
    'range="-0.5 0.5" limited="false"',
    'range="-0.5 0.5" limited="false" damping="0.05"',
    'range="-0.2 0.2" limited="false"',
    """<tendon>
    <fixed name="ab" range="-0.3 0.2" margin="0.02" solimplimit="0.8 0.95 0.05 0.4 3">
      <joint joint="a" coef="1"/><joint joint="b" coef="0.5"/>
    </fixed>
    <fixed name="cb" range="-0.4 0.3" solreflimit="-3000 -40" frictionloss="0.2" solreffriction="0.03 0.8">
      <joint joint="c" coef="2"/><joint joint="b" coef="-1"/>
    </fixed>
  </tendon>""",
)


@pytest.mark.parametrize("mistake", [None, "no_tendon_rows", "weight_of_a_joint", "friction_unbounded"])
def test_the_laws_tendon_limit_and_frictionloss_rows_are_mujocos(mistake):
    """A chain with two fixed tendons, each limited (a margin and a solimp sigmoid on one, the direct solref form on
    the other), the second with frictionloss: at 32 random states about and past the tendons' ends, half of them
    nearly still, the law's end velocity is MuJoCo's step's with the tendons' rows, measured 1.4e-6 relative
    (`STEP_TOLERANCE`). Each mistake misses: the tendons' rows left out (2.0), their diagApprox a joint's invweight0
    rather than the tendon's (0.53), frictionloss's force left unbounded (0.95)."""
    result, dofs, plan, inertia = _loaded_law(TENDON_ROWS)
    rows = plan.tendon_rows
    assert rows.limits.limited.tolist() == [True, True] and rows.friction.loss.tolist() == [0.0, 0.2]
    assert not plan.not_carried
    if mistake == "no_tendon_rows":
        rows.limits.limited[:], rows.friction.weight[:] = False, 0.0
    elif mistake == "weight_of_a_joint":
        rows.limits.diag_approx[:] = result.model.dof_invweight0[0]
    elif mistake == "friction_unbounded":
        rows.friction.loss[:] = np.inf
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.5)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


CLOSED_CHAIN = Path(__file__).resolve().parents[1] / "corpus" / "fixtures" / "closed_chain.xml"


@pytest.mark.parametrize("mistake", [None, "one_anchor", "weight_of_a_dof", "no_rate", "no_connect"])
def test_the_laws_connects_are_mujocos(monkeypatch, mistake):
    """The corpus's closed chain, two legs pinned at their tips by a connect (a five-bar loop on a fixed base): at 32
    random states, the pin pulled apart by each, the law's end velocity is MuJoCo's step's with the connect's rows,
    measured 9.6e-7 relative (`STEP_TOLERANCE`). Each mistake misses: both ends at body1's anchor (2.9), the rows'
    diagApprox a DoF's invweight0 (0.30), the reference without MuJoCo's dJ/dt v correction (2.1e-2), the connect
    left out (1.1)."""
    result, dofs, plan, inertia = _loaded_law(CLOSED_CHAIN.read_text())
    connects = plan.connects
    assert connects.links.shape == (1, 2) and not plan.not_carried
    if mistake == "one_anchor":
        connects.points[:, 1] = connects.points[:, 0]
    elif mistake == "weight_of_a_dof":
        connects.diag_approx[:] = result.model.dof_invweight0[0]
    elif mistake == "no_rate":
        placed = constraint_rows.points_and_jacobians
        monkeypatch.setattr(
            constraint_rows, "points_and_jacobians", lambda *a: (*placed(*a)[:2], torch.zeros_like(placed(*a)[2]))
        )
    elif mistake == "no_connect":
        plan.connects = type(connects).none()
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


# rad, the closed chain's joints in Empty-v1 under mujoco_ctrl_tensor against MuJoCo over 1 s, a 0.2 N m sine on the
# hip (TGS): measured 7.8e-5 (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0, torch 2.13.0); with the connect's D6
# joint left locked 0.29, with the connect left out of the law (its D6 locked alone) 0.34
LOOP_TOLERANCE = 5e-4


def _tensor_env(path: Path, uid: str):
    """MuJoCo's model and data of `path`, and `Empty-v1` at 500 Hz with it registered as `uid` under
    `mujoco_ctrl_tensor`."""
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, uid, override=True)
        env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50)
    return model, mujoco.MjData(model), env


@pytest.mark.parametrize("case", [None, "gpu_build", "d6_locked", "connect_left_out"])
def test_a_closed_chain_follows_mujoco_with_its_connect_in_the_law(monkeypatch, case):
    """The closed chain's five-bar swung by its hip in `Empty-v1` under `mujoco_ctrl_tensor`: the law carries its
    connect as MuJoCo's soft rows and the connect's PhysX D6 joint stands free, so the joints follow MuJoCo stepping
    the same ctrl, also where the robot is built as for the GPU backend (no `LoadResult`; its D6 built free). With
    the D6 left locked, PhysX holds the pin rigidly against the soft rows; with the connect left out of the law, the
    locked D6 alone holds it; either mistake parts from MuJoCo."""
    from loader.maniskill import agent as agent_module
    from loader.maniskill import scene_loader

    if case == "gpu_build":
        monkeypatch.setattr(scene_loader, "per_step_terms", lambda scene: False)
    elif case == "d6_locked":
        monkeypatch.setattr(agent_module.MJCFAgent, "_loops_for", lambda agent, mode, gpu: None)
    elif case == "connect_left_out":
        planned = agent_module.plan_joint_actuation

        def without_connects(*args):
            law = planned(*args)
            law.connects = type(law.connects).none()
            return law

        monkeypatch.setattr(agent_module, "plan_joint_actuation", without_connects)
    model, data, env = _tensor_env(CLOSED_CHAIN, f"tensor_chain_{case}")
    try:
        env.reset(seed=0)
        robot, worst = env.unwrapped.agent.robot, 0.0
        order = [robot.active_joints_map[model.joint(j).name].active_index[0] for j in range(model.njnt)]
        for step in range(50):
            ctrl = np.array([0.2 * np.sin(2 * np.pi * step / 25)], np.float32)
            env.step(ctrl)
            data.ctrl[:] = ctrl
            for _ in range(10):
                mujoco.mj_step(model, data)
            worst = max(worst, float(np.abs(robot.get_qpos()[0].numpy()[order] - data.qpos).max()))
    finally:
        env.close()
    assert (worst < LOOP_TOLERANCE) == (case in (None, "gpu_build")), worst


def _chain_pinned_by_sites() -> str:
    """The closed chain with its pin given by two sites, one at each leg's tip."""
    xml = CLOSED_CHAIN.read_text()
    for tip in (
        'fromto="0 0 0 .1 0 -.15" size=".012" mass=".05"/>',
        'fromto="0 0 0 -.1 0 -.15" size=".012" mass=".04"/>',
    ):
        side, at = ("left", ".1 0 -.15") if 'mass=".05"' in tip else ("right", "-.1 0 -.15")
        xml = xml.replace(tip, f'{tip}<site name="{side}_tip" pos="{at}"/>')
    pin = '<connect name="pin" body1="left_lower" body2="right_lower" anchor=".1 0 -.15"/>'
    return xml.replace(pin, '<connect name="pin" site1="left_tip" site2="right_tip"/>')


@pytest.mark.parametrize("mistake", [None, "tips_swapped"])
def test_a_connect_by_site_is_the_laws_too(mistake):
    """The closed chain pinned by two sites (MuJoCo's site semantic: each anchor the site, on its body): at 32 random
    states the law's end velocity is MuJoCo's step's, as with the pin given by body (9.6e-7 relative). With the two
    tips swapped, it misses (7.3)."""
    result, dofs, plan, inertia = _loaded_law(_chain_pinned_by_sites())
    assert int(result.model.eq_objtype[0]) == int(mujoco.mjtObj.mjOBJ_SITE) and plan.connects.links.shape == (1, 2)
    if mistake:
        plan.connects.points[0] = plan.connects.points[0][::-1]
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


WELDED_LEGS = Path(__file__).resolve().parents[1] / "corpus" / "fixtures" / "welded_legs.xml"


@pytest.mark.parametrize("mistake", [None, "no_rate", "torquescale_one", "no_weld"])
def test_the_laws_welds_are_mujocos(monkeypatch, mistake):
    """The corpus's welded legs, their feet welded (an anchor off the foot's origin, torquescale 2) on legs of two
    hinges a link: at 32 random states the law's end velocity is MuJoCo's step's with the weld's six rows, measured
    5.5e-7 relative (`STEP_TOLERANCE`). Each mistake misses: the rows' reference without MuJoCo's dJ/dt v (1.4e-2),
    torquescale taken as one (0.27), the weld left out (1.3)."""
    result, dofs, plan, inertia = _loaded_law(WELDED_LEGS.read_text())
    welds = plan.welds
    assert welds.links.shape == (1, 2) and not plan.not_carried
    if mistake == "no_rate":
        for name in ("points_and_jacobians", "turning"):
            placed = getattr(constraint_rows, name)
            monkeypatch.setattr(
                constraint_rows, name, lambda *a, placed=placed: (*placed(*a)[:-1], torch.zeros_like(placed(*a)[-1]))
            )
    elif mistake == "torquescale_one":
        welds.torquescale[:] = 1.0
    elif mistake == "no_weld":
        plan.welds = type(welds).none()
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


def _floating(fixture: Path) -> str:
    """A corpus fixture whose base, fixed to the world there, floats on a free joint."""
    xml = fixture.read_text()
    assert xml.count('<body name="base" pos="0 0 1">') == 1
    return xml.replace('<body name="base" pos="0 0 1">', '<body name="base" pos="0 0 1"><freejoint/>')


@pytest.mark.parametrize("mistake", [None, "no_loops", "root_force_left_out", "no_root_columns", "no_root_rate"])
@pytest.mark.parametrize("fixture", [CLOSED_CHAIN, WELDED_LEGS], ids=["connect", "weld"])
def test_loops_on_a_floating_chain_are_mujocos(monkeypatch, fixture, mistake):
    """The closed chain and the welded legs on a floating base: at 32 random states and root motions, the law's end
    velocity of the joints and of the root is MuJoCo's step's with the loop's rows, measured 9.4e-7 (connect) and
    5.3e-7 (weld) relative (`STEP_TOLERANCE`). The rows' Jacobians take the free joint's six columns and their
    reference its share of dJ/dt v, and the root's step takes the rows' force on it. Each mistake misses (connect,
    weld): the loop left out (1.0, 1.2), the rows' force left off the root's step (1.0e-2, 1.3e-2), the root's columns
    left out of the rows' Jacobians (6.6e-2, 0.23), the root's share of dJ/dt v left out (7.9e-3, 8.6e-3)."""
    result, dofs, plan, inertia = _loaded_law(_floating(fixture))
    assert inertia.floating and len(plan.connects.links) + len(plan.welds.links) == 1
    assert OTHER_EQUALITIES not in plan.not_carried
    if mistake == "no_loops":
        plan.connects, plan.welds = type(plan.connects).none(), type(plan.welds).none()
    elif mistake == "root_force_left_out":
        monkeypatch.setattr(
            joint_actuation.ImplicitStep, "root_rows", lambda step, *a: RootRows.solve(step.matrix, step.bias, *a)
        )
    elif mistake == "no_root_columns":
        for name in ("points_and_jacobians", "turning"):
            placed = getattr(constraint_rows, name)

            def rootless(*args, placed=placed):  # the Jacobian, second of either's outputs, zero in the root's rows
                out = list(placed(*args))
                out[1] = torch.nn.functional.pad(out[1][:, :, 6:], (0, 0, 6, 0))
                return tuple(out)

            monkeypatch.setattr(constraint_rows, name, rootless)
    elif mistake == "no_root_rate":
        placed = constraint_rows.points_and_jacobians

        def unturned(law, moved, v, links, local):
            point, jacobian, rate = placed(law, moved, v, links, local)
            velocity = (jacobian * moved.speed[:, None, :, None]).sum(2)
            return point, jacobian, rate - inertia_module._root_rate(moved, velocity)

        monkeypatch.setattr(constraint_rows, "points_and_jacobians", unturned)
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst


# m or rad: the largest |ManiSkill - MuJoCo| of the floating closed chain's and welded legs' qpos (the free joint's
# among them) over 0.5 s of a 0.2 N m sine under mujoco_ctrl_tensor and TGS (mani-skill 3.0.1, sapien 3.0.3, mujoco
# 3.17.0, torch 2.13.0): measured 1.8e-5 (connect) and 1.2e-5 (weld); with the loop's D6 joint left locked 7.8e-3 and
# 5.1e-2, with qf not taking off what the loop's force on the root moves the joints by 5.5e-4 and 1.2e-4
FLOATING_LOOP_TOLERANCE = 5e-5


@pytest.mark.parametrize("case", [None, "d6_locked", "qf_unpushed"])
@pytest.mark.parametrize("fixture", [CLOSED_CHAIN, WELDED_LEGS], ids=["connect", "weld"])
def test_a_floating_loop_follows_mujoco_in_empty_v1(tmp_path, monkeypatch, fixture, case):
    """The closed chain and the welded legs falling on a free joint in `Empty-v1` under `mujoco_ctrl_tensor`, the hip
    swung by a sine: root and joints follow MuJoCo stepping the same ctrl. PhysX's root takes no force, so `qf` takes
    off what the loop's force on the root would move the joints by, and the root's settle gives the root its share.
    With the loop's D6 joint left locked PhysX holds the loop rigidly against the soft rows; without that share
    taken off, the joints miss MuJoCo's end velocity every step."""
    from loader.maniskill import agent as agent_module

    if case == "d6_locked":
        monkeypatch.setattr(agent_module.MJCFAgent, "_loops_for", lambda agent, mode, gpu: None)
    path = tmp_path / f"floating_{fixture.name}"
    path.write_text(_floating(fixture))
    model, data, env = _tensor_env(path, f"tensor_floating_{fixture.stem}_{case}")
    try:
        env.reset(seed=0)
        (result,) = env.unwrapped.agent.results
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        if case == "qf_unpushed":
            controller.law.any_loops = False
        result.set_state(data.qpos, data.qvel)
        worst = 0.0
        for step in range(25):
            data.ctrl[:] = np.float32(0.2 * np.sin(2 * np.pi * step / 25))
            env.step(data.ctrl.astype(np.float32))
            for _ in range(10):
                mujoco.mj_step(model, data)
            controller.settle()
            worst = max(worst, float(np.abs(result.get_state()[0] - data.qpos).max()))
    finally:
        env.close()
    assert (worst < FLOATING_LOOP_TOLERANCE) == (case is None), worst


def test_the_robot_is_the_tree_the_actuators_drive(tmp_path):
    """A scene file whose table, a tree of its own, comes before the stiff servo arm: the agent's robot is the arm,
    the tree its actuators drive, with its PD modes and `mujoco_ctrl_tensor`, whose law follows MuJoCo on it (PGS,
    `TENSOR_FOLLOW_TOLERANCE`); `mujoco_ctrl` is not offered (its per-step terms need the model to be one tree).
    Taking the first tree, as ManiSkill's own agent does, makes the table the robot: no mode drives the arm."""
    xml = (FIXTURES / "folding_servo_arm.xml").read_text()
    table = '<body name="table" pos="0 0 -1"><geom type="box" size=".5 .5 .05" contype="0" conaffinity="0"/></body>'
    path = tmp_path / "arm_beside_a_table.xml"
    path.write_text(xml.replace("<worldbody>", f"<worldbody>{table}", 1))
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, "arm_beside_a_table", override=True)
        env = empty_env(agent.uid, "pd_joint_pos", 500, 50)
    try:
        env.reset(seed=0)
        assert env.unwrapped.agent.robot.dof[0] == model.nv == 3
        modes = env.unwrapped.agent.supported_control_modes
        assert "mujoco_ctrl_tensor" in modes and "pd_joint_delta_pos" in modes and "mujoco_ctrl" not in modes
    finally:
        env.close()
    assert _follow(agent.uid, model) < TENSOR_FOLLOW_TOLERANCE["pgs"]


WRAPPED_TENDONS = FIXTURES / "wrapped_tendons.xml"
AERO_HAND = "tetheria_aero_hand_open/right_hand.xml"
# m and relative: the spatial tendons' lengths and Jacobians against MuJoCo's ten_length and ten_J at 64 random
# states (float32 link frames in both; mujoco 3.17.0, sapien 3.0.3, torch 2.13.0): measured 1.0e-7 m and 1.5e-6 on
# the fixture, 2.1e-8 m and 7.6e-7 on the aero hand; with the wraps left out 2.3e-2 m and 1.5, 4.2e-3 m and 0.43
SPATIAL_LENGTH_TOLERANCE = 1e-6
SPATIAL_JACOBIAN_TOLERANCE = 1e-5


def _tendon_model(name: str) -> Path:
    """The fixture, or the Menagerie aero hand (skipped without the slice)."""
    if name == "fixture":
        return WRAPPED_TENDONS
    from support.corpus import menagerie_root

    root = menagerie_root()
    if root is None or not (root / AERO_HAND).is_file():
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    return root / AERO_HAND


def _tendon_states(model, joints, rng, count: int):
    """`count` joint positions within the middle 60 % of each limited joint's range (1 rad about zero where
    unlimited)."""
    low, high = model.jnt_range[joints].T
    middle, half = (low + high) / 2, 0.3 * (high - low)
    for _ in range(count):
        yield np.where(
            model.jnt_limited[joints], rng.uniform(middle - half, middle + half), rng.uniform(-1, 1, len(joints))
        )


@pytest.mark.parametrize("mistake", [None, "no_wraps"])
@pytest.mark.parametrize("name", ["fixture", "aero_hand"])
def test_spatial_tendons_are_mujocos(name, mistake):
    """The law's spatial tendons against MuJoCo's tendon pass at 64 random states: lengths within
    `SPATIAL_LENGTH_TOLERANCE`, Jacobians within `SPATIAL_JACOBIAN_TOLERANCE` relative, on the fixture (a sphere
    without a sidesite into a pulley's two branches, a cylinder whose sidesite picks its side, a strap of sites) and
    on the Menagerie aero hand (cylinders with sidesites), with segments both wrapped and straight among the states.
    With the wraps left out (every segment straight), they miss."""
    from loader.maniskill.inertia import motion
    from loader.maniskill.spatial_tendons import spatial_tendons

    result, dofs, plan, inertia = _loaded_law(_tendon_model(name))
    model, law = result.model, Law(plan, result.model.opt.timestep, "cpu", torch.float64)
    if mistake == "no_wraps":
        law.spatial.wraps = law.spatial.wraps[:0]
    tendons = plan.spatial.tendons.tendons
    assert tendons and not plan.not_carried
    joints = sorted(dofs, key=dofs.get)
    root = result.articulations[0].get_root_pose()
    pose = torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None]
    data, dense = mujoco.MjData(model), np.zeros((model.ntendon, model.nv))
    lengths, jacobians, wraps = 0.0, 0.0, set()
    for q in _tendon_states(model, joints, np.random.default_rng(0), 64):
        data.qpos[model.jnt_qposadr[joints]] = q
        mujoco.mj_fwdPosition(model, data)
        moved = motion(inertia, torch.tensor(q)[None], torch.zeros(1, len(q), dtype=torch.float64), pose)
        length, jacobian = (x[0].numpy() for x in spatial_tendons(law.spatial, inertia, moved))
        mujoco.mju_sparse2dense(dense, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
        expected = dense[tendons][:, model.jnt_dofadr[joints]]
        lengths = max(lengths, float(np.abs(length - data.ten_length[tendons]).max()))
        jacobians = max(jacobians, float(np.abs(jacobian - expected).max() / np.abs(expected).max()))
        for t in tendons:  # a wrapping tendon's path holds the geom's id among its points
            start, count = data.ten_wrapadr[t], data.ten_wrapnum[t]
            geoms = [
                w
                for w in range(model.tendon_adr[t], model.tendon_adr[t] + model.tendon_num[t])
                if model.wrap_type[w] > 3
            ]
            if geoms:
                wraps.add(bool(np.any(data.wrap_obj.reshape(-1)[start : start + count] >= 0)))
    agree = lengths < SPATIAL_LENGTH_TOLERANCE and jacobians < SPATIAL_JACOBIAN_TOLERANCE
    assert agree == (mistake is None), (lengths, jacobians)
    assert wraps == {True, False}


def _worst_tendon_step(result, dofs, plan, inertia, law: Law) -> float:
    """The largest relative |law - MuJoCo| end velocity over 32 random states (`_tendon_states`), joint velocities
    and ctrls within ctrlrange, MuJoCo's contacts off and its rows on."""
    model = result.model
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    joints = sorted(dofs, key=dofs.get)
    qpos, qvel = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    root = result.articulations[0].get_root_pose()
    pose = torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None]
    data, rng, worst = mujoco.MjData(model), np.random.default_rng(0), 0.0
    low, high = model.actuator_ctrlrange.T
    for q in _tendon_states(model, joints, rng, 32):
        mujoco.mj_resetData(model, data)
        data.qpos[qpos], data.qvel[qvel], data.ctrl[:] = q, rng.uniform(-1, 1, len(joints)), rng.uniform(low, high)
        state = torch.tensor(data.qpos[qpos])[None], torch.tensor(data.qvel[qvel])[None]
        end = implicit_step(law, inertia, torch.tensor(data.ctrl)[None], *state, pose).end[0].numpy()
        mujoco.mj_step(model, data)
        worst = max(worst, float(np.abs(end - data.qvel[qvel]).max() / max(1.0, np.abs(data.qvel[qvel]).max())))
    return worst


@pytest.mark.parametrize("mistake", [None, "no_springs", "no_wraps", "dampers_explicit", "no_rows"])
@pytest.mark.parametrize("name", ["fixture", "aero_hand"])
def test_the_laws_spatial_tendons_are_mujocos(name, mistake):
    """The law's step with spatial tendons against `mj_step` (contacts off) at 32 random states: their actuators'
    forces through their moments at the state, their springs and dampers, what MuJoCo's step takes implicitly of
    them (the fixture's servo kv and strap damper), and their limit and frictionloss rows (the fixture's drum tendon
    and strap), within `STEP_TOLERANCE`. Measured 8.5e-6 (fixture) and 1.6e-6 (aero hand). Each mistake misses
    (fixture, aero hand): the springs left out 0.19 and 8.1e-2, the wraps left out 1.4 and 0.28, the dampers and kv
    taken explicitly 3.7e-2, the rows left out 2.8 (the aero hand has neither). The aero hand's frictionloss is off
    on both sides: with it and its couplings, MuJoCo's Newton solver stops after one iteration at 2 of these states,
    short of its own optimum (MuJoCo's cost at the law's acceleration is the lower), and parts from the law by
    2.0e-3; its row solve is the frictionloss tests' and the couplings tests'."""
    result, dofs, plan, inertia = _loaded_law(_tendon_model(name))
    assert plan.spatial.tendons.count and not plan.not_carried
    if name == "aero_hand":
        result.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
        plan.friction = type(plan.friction).none(plan.ndof)
    if mistake == "no_springs":
        plan.spatial.stiffness[:] = 0.0
    elif mistake == "dampers_explicit":
        plan.spatial.implicit_damping[:] = 0.0
        plan.velocity_gain[plan.spatial.actuator >= 0] = 0.0
    elif mistake == "no_rows":
        plan.spatial = replace(plan.spatial, rowed=plan.spatial.rowed[:0], limits=type(plan.limits).none(0))
        plan.spatial.friction = type(plan.friction).none(0)
    law = Law(plan, result.model.opt.timestep, "cpu", torch.float64)
    if mistake == "no_wraps":
        law.spatial.wraps = law.spatial.wraps[:0]
    worst = _worst_tendon_step(result, dofs, plan, inertia, law)
    wrong = mistake is not None and not (mistake in ("dampers_explicit", "no_rows") and name == "aero_hand")
    assert (worst > STEP_TOLERANCE) == wrong, worst


@pytest.mark.parametrize("mistake", [None, "no_springs"])
def test_spatial_tendons_on_a_floating_base_are_mujocos(mistake):
    """The wrapped tendons' fixture on a free joint: at 32 random states and root motions the law's end velocity of
    the joints and of the root is MuJoCo's step's (`STEP_TOLERANCE`), measured 6.8e-6. A tendon's length does not
    change as the whole tree moves, so the root's columns of its Jacobian are zero and its forces act on the joints
    alone. With the strap's spring left out, it misses by 0.15."""
    xml = WRAPPED_TENDONS.read_text()
    result, dofs, plan, inertia = _loaded_law(
        xml.replace('<body name="base" pos="0 0 1">', '<body name="base" pos="0 0 1"><freejoint/>')
    )
    assert inertia.floating and plan.spatial.tendons.count == 3
    if mistake == "no_springs":
        plan.spatial.stiffness[:] = 0.0
    worst = _worst_rows_step(result, dofs, plan, inertia, slow=0.0)
    assert (worst < STEP_TOLERANCE) == (mistake is None), worst
