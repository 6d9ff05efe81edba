"""`mujoco_ctrl_tensor`: the joint actuation law (loader/plan/joint_actuation.py) over (env, DoF) tensors in
ManiSkill (loader/maniskill/joint_actuation.py). MuJoCo is the oracle: the law's force and its drives' force are
MuJoCo's actuator and passive forces at any state, and the mode follows MuJoCo stepped with the same ctrl under PGS.
Needs torch and mani_skill (the `maniskill` extra); the CUDA test skips without a GPU."""

from __future__ import annotations

import re
import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, corpus_params, suite_path

torch = pytest.importorskip("torch", reason="torch is not installed (the `maniskill` extra)")
pytest.importorskip("mani_skill", reason="mani_skill is not installed (the `maniskill` extra)")

from test_joint_actuation import ACTUATED, DOF_OF_JOINT, SPATIAL

from conformance.tiers.maniskill import empty_env
from loader import SceneMismatchWarning
from loader.maniskill import register_agent
from loader.maniskill.joint_actuation import Law, joint_forces, next_activation
from loader.plan.joint_actuation import plan_joint_actuation, robot_indices


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
    """A small mistake in the plan: the position servo's spring left out, the joint's actuatorfrcrange left out, or
    each kv on the wrong side (in the law where the drive holds it, out of it where the drive does not)."""
    if name == "no_position_gain":
        plan.bias[1, 0] = 0.0
    elif name == "no_joint_range":
        plan.joint_range[:, 0] = [-np.inf, np.inf]
    elif name == "kv_misplaced":
        plan.held[:] = np.where(plan.bias[2] < 0, 1.0 - plan.held, plan.held)


@pytest.mark.parametrize("mistake", [None, "no_position_gain", "no_joint_range", "kv_misplaced"])
@pytest.mark.parametrize("integrator", ["implicitfast", "Euler", "implicitfast group off"])
def test_the_law_and_its_drives_give_mujocos_actuator_and_passive_force(integrator, mistake):
    """At 64 random states, activations and ctrls (past ctrlrange, binding forcerange and actuatorfrcrange), with
    the drives aimed at the state's velocity (so they pull nothing there), the law's joint force is MuJoCo's
    actuator and passive force, to float64 rounding, in float64 on the CPU, also with the motor's actuator group
    disabled; each mistake breaks it."""
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
    qf = joint_forces(law, *state, act=torch.as_tensor(np.array([_acts(model, a) for a in act]))).numpy()
    error = np.abs(qf - _mujoco_forces(model, q, v, ctrl, act)).max()  # the drives aimed at v: no pull at v
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


# rad, the largest |ManiSkill - MuJoCo| joint position of the stiff servo arm over 0.5 s under mujoco_ctrl_tensor,
# PGS (mani-skill 3.0.1, sapien 3.0.3, mujoco 3.17.0, torch 2.13.0): measured 1.2e-6 (PhysX's float32 step); with each
# kv misplaced 0.53; under TGS, whose drives damp over their iterations, 0.56. With every body compensated fully
# (gravcomp 1): 1.5e-6; with the links left weighing 6.8e-4. Each servo behind a 10 ms filter: 2.4e-6; with the
# activations never stepped 2.9
TENSOR_FOLLOW_TOLERANCE = 1e-5
# rad, the Menagerie panda's arm joints the same way: its servos saturate (forcerange) through most of the sine, where
# MuJoCo's force has no implicit term and the drive's pull is left aimed at the end velocity. Measured 8.7e-3 with the
# drives aimed at the extrapolated end velocity (1.9e-2 under TGS), 0.13 at the start velocity (same versions). Beyond
# the law: the stiff servo arm given a forcerange of 30 misses by radians either way (dt kv is a thousand times its
# wrist's inertia, and only M would say where a saturated joint ends)
SATURATED_TOLERANCE = 2e-2


@pytest.mark.parametrize("mistake", [None, "kv_misplaced"])
def test_mujoco_ctrl_tensor_follows_mujoco_under_pgs_on_the_cpu_backend(mistake):
    """The stiff servo arm (kp 5000, kv 200 on light links) in `Empty-v1` under `mujoco_ctrl_tensor`, PGS: it
    follows MuJoCo; with the drives' kv also in the law it does not; under TGS the mode warns and does not follow."""
    path = FIXTURES / "folding_servo_arm.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_arm_{mistake}", override=True)
    _mistaken(mistake, agent.joint_actuation)
    worst = _follow(agent.uid, model)
    assert (worst < TENSOR_FOLLOW_TOLERANCE) == (mistake is None), worst
    if mistake is None:
        with pytest.warns(SceneMismatchWarning, match="enable_tgs=False"):
            assert _follow(agent.uid, model, tgs=True) > 100 * TENSOR_FOLLOW_TOLERANCE


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


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA (ManiSkill's physx_cuda backend)")
def test_mujoco_ctrl_tensor_steps_every_sub_scene_on_the_gpu():
    """On `physx_cuda` with 4 sub-scenes, the mode's `qf` on the device is the law's for each sub-scene's own state
    (the same code as on the CPU, one launch per operation for all of them)."""
    import gymnasium as gym

    path = FIXTURES / "folding_servo_arm.xml"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, "tensor_arm_gpu", override=True)
        env = gym.make(
            "Empty-v1",
            robot_uids=agent.uid,
            num_envs=4,
            sim_backend="physx_cuda",
            render_backend="none",
            obs_mode="state",
            control_mode="mujoco_ctrl_tensor",
            sim_config={"sim_freq": 500, "control_freq": 50, "scene_config": {"enable_tgs": False}},
        )
    try:
        env.reset(seed=0)
        unwrapped = env.unwrapped
        ctrl = torch.linspace(-0.5, 0.5, 4 * 3, device=unwrapped.device).reshape(4, 3)
        env.step(ctrl)
        robot, controller = unwrapped.agent.robot, unwrapped.agent.controller.controllers["ctrl"]
        unwrapped.scene.px.gpu_fetch_articulation_qpos()
        unwrapped.scene.px.gpu_fetch_articulation_qvel()
        q, v = robot.get_qpos().double(), robot.get_qvel().double()
        target, act = controller.end_velocity(v), controller.act.clone()
        controller.before_simulation_step()
        expected = joint_forces(controller.law, controller.ctrl, q, v, target, act).float()
        assert torch.allclose(robot.get_qf(), expected)
        assert torch.allclose(robot.get_drive_velocities(), target.float())  # ManiSkill's own reader
        assert not torch.allclose(expected[0], expected[1])  # each sub-scene its own ctrl and state
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
    assert (worst < TENSOR_FOLLOW_TOLERANCE) == (mistake is None), worst


@pytest.mark.parametrize("mistake", [None, "start_velocity"])
def test_a_saturated_arm_aims_its_drives_at_the_extrapolated_velocity(monkeypatch, mistake):
    """The panda's arm under a sine that saturates its servos follows MuJoCo within `SATURATED_TOLERANCE`: where a
    clamp binds, the drive's pull is left aimed at the end velocity extrapolated from the last step; aimed at the
    start velocity instead, the arm misses."""
    from support.corpus import menagerie_root

    from loader.maniskill import joint_actuation

    root = menagerie_root()
    if root is None:
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    path = root / "franka_emika_panda/panda.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent = register_agent(path, f"tensor_panda_{mistake}", override=True)
    if mistake:
        monkeypatch.setattr(joint_actuation.JointActuationController, "end_velocity", lambda self, v: v)
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
    (its drives aimed at the state's velocity: no pull there) and MuJoCo's actuator and passive force less what the
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
        force = joint_forces(law, torch.as_tensor(data.ctrl[None].copy()), torch.as_tensor(q), torch.as_tensor(v))
        got = force.numpy()[0, robot]
        worst = max(worst, float(np.abs(got - expected).max() / max(1.0, np.abs(expected).max())))
    return worst


@pytest.mark.parametrize("path", corpus_params())
def test_the_law_is_mujocos_on_every_corpus_robot_it_takes(path):
    """Robot by robot over the default corpus: where the law takes the model, its force is MuJoCo's to float64
    rounding (`_worst_law_error`); where it does not, it says why in words. Models whose tendons have springs or
    dampers are skipped."""
    model, dofs, plan = _planned(path)
    if not model.nu or not dofs:
        pytest.skip("no actuator, or no hinge or slide: nothing for the law")
    if isinstance(plan, str):
        assert plan.startswith("actuator '"), plan  # names the actuator, and why
        return
    if np.any(model.tendon_stiffness) or np.any(model.tendon_damping):
        pytest.skip("tendon springs and dampers: listed as not carried")
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
    activations, ctrl and last step as they were, so its drives go on aiming at the extrapolated end velocity; a reset
    of every env restarts them. Mutation: the agent's mark not handed to the controller, which then resets every
    env."""
    from loader.maniskill.agent import MJCFAgent

    model, agent = _filtered_arm(tmp_path, f"tensor_partial_{mistake}")
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        if mistake:
            env.unwrapped.agent.reset = lambda init_qpos=None: super(MJCFAgent, env.unwrapped.agent).reset(init_qpos)
        env.step(np.full(model.nu, 0.5, np.float32))
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        act, ctrl, previous = controller.act.clone(), controller.ctrl.clone(), controller.previous
        assert float(act.abs().min()) > 0.1 and previous is not None
        env.reset(seed=1, options={"env_idx": torch.tensor([], dtype=torch.long)})
        kept = (
            torch.equal(controller.act, act)
            and torch.equal(controller.ctrl, ctrl)
            and controller.previous is previous
            and controller.fresh is None
        )
        assert kept == (mistake is None)
        env.reset(seed=2)
        assert float(controller.act.abs().max()) == 0.0 and controller.previous is None
    finally:
        env.close()


@pytest.mark.parametrize("mistake", [None, "fresh_ignored"])
def test_a_reset_env_aims_at_its_own_velocity_while_the_others_extrapolate(tmp_path, mistake):
    """Two envs' rows (as on the GPU backend), the first reset: its ctrl and activations restart at zero and its
    drives aim at its velocity, while the second keeps its activations and aims at 2 v - v_prev. Mutation: the
    reset env extrapolated from its last episode's velocity."""
    _, agent = _filtered_arm(tmp_path, f"tensor_fresh_{mistake}")
    env = empty_env(agent.uid, "mujoco_ctrl_tensor", 500, 50, {"enable_tgs": False})
    try:
        env.reset(seed=0)
        controller = env.unwrapped.agent.controller.controllers["ctrl"]
        rows = torch.tensor([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], dtype=torch.float64)
        controller.ctrl, controller.act, controller.previous = rows.clone(), rows.clone(), -rows
        controller.resetting = torch.tensor([True, False])
        controller.reset()
        if mistake:
            controller.fresh = None
        assert controller.ctrl[0].abs().max() == 0.0 and controller.act[0].abs().max() == 0.0
        assert torch.equal(controller.ctrl[1], rows[1]) and torch.equal(controller.act[1], rows[1])
        aim = controller.end_velocity(rows)
        assert torch.equal(aim[1], 3.0 * rows[1])  # 2 v - (-v)
        assert torch.equal(aim[0], rows[0]) == (mistake is None)
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
    assert (worst < TENSOR_FOLLOW_TOLERANCE) == (mistake is None), worst
