"""Actuators, tendons and equality constraints: both simulators receive the same ctrl; MuJoCo is the oracle.

Contact is off on both sides and MuJoCo integrates with implicitfast, the integrator the drive mapping assumes.
Tolerances are measured: unsaturated panda servos agree to 3e-6 rad over 1 s; the coupled-joint fixture to
4.4e-3 rad over 2 s (MuJoCo's soft equality as a PhysX tendon spring: see loader/build/equalities.py); the panda and
2f85 grippers to 5e-4 and 3.3e-4 while closing.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, menagerie_root

from loader import MJCFLoader

SERVO_TOLERANCE = 2e-5  # rad, measured 3e-6
COUPLING_TOLERANCE = 1e-2  # rad, measured 4.4e-3 (soft equality)
GRIPPER_TOLERANCE = 1e-3  # rad or m, measured 3.3e-4 (5e-4 with rigid connects)
needs_menagerie = pytest.mark.skipif(menagerie_root() is None, reason="Menagerie slice not installed")


def _contact_free(path, mutate=None):
    result = MJCFLoader().load(path)
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    if mutate:
        mutate(result)
    return result, model


def _replay(result, model, ctrl_at, seconds: float, reference=None) -> np.ndarray:
    """Step both simulators under the same ctrl sequence; the worst |qpos| difference per step.
    `reference` is the model MuJoCo runs (default: the loaded one)."""
    reference = reference or model
    data = mujoco.MjData(reference)
    key = 0 if reference.nkey else None
    if key is None:
        mujoco.mj_resetData(reference, data)
    else:
        mujoco.mj_resetDataKeyframe(reference, data, key)
    result.reset(key)
    errors = []
    for step in range(int(seconds / reference.opt.timestep)):
        ctrl = ctrl_at(step, data)
        data.ctrl[:] = ctrl
        result.set_ctrl(ctrl)
        mujoco.mj_step(reference, data)
        result.scene.step()
        qpos, _ = result.mapping.get_state(result.articulations)
        errors.append(np.abs(qpos - data.qpos).max())
    return np.array(errors)


def _small_steps(model, seed=0, size=0.001):
    rng = np.random.default_rng(seed)
    low, high = model.actuator_ctrlrange.T
    span = np.where(model.actuator_ctrllimited, high - low, 2.0)
    initial = model.key_ctrl[0].copy() if model.nkey else np.zeros(model.nu)
    target = initial + size * span * rng.uniform(-1, 1, model.nu)

    def ctrl_at(step, data):
        return initial if step < 100 else target

    return ctrl_at


@needs_menagerie
def test_panda_position_servos_track_like_mujoco():
    result, model = _contact_free(menagerie_root() / "franka_emika_panda/panda.xml")
    assert all(a.mapped for a in result.actuators)
    errors = _replay(result, model, _small_steps(model), 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()


@needs_menagerie
def test_a_five_percent_kp_error_is_caught():
    def mutate(result):
        for drive in result.controller.laws().values():
            if drive.stiffness > 0:
                drive.stiffness *= 1.05

    result, model = _contact_free(menagerie_root() / "franka_emika_panda/panda.xml", mutate)
    errors = _replay(result, model, _small_steps(model), 1.0)
    assert errors.max() > SERVO_TOLERANCE


def _fixture_ctrl(step, data):
    return np.array([np.sin(step * 0.01), 0.3 * np.cos(step * 0.005)])


def test_motor_servo_and_joint_coupling_match_mujoco():
    result, model = _contact_free(FIXTURES / "coupled_joints.xml")
    errors = _replay(result, model, _fixture_ctrl, 2.0)
    assert errors.max() < COUPLING_TOLERANCE, errors.max()


def test_set_ctrl_clamps_to_ctrlrange():
    result, model = _contact_free(FIXTURES / "coupled_joints.xml")
    errors = _replay(result, model, lambda step, data: np.array([5.0, -3.0]), 0.5)
    assert errors.max() < COUPLING_TOLERANCE


@pytest.mark.parametrize("edit", [('gear="2"', 'gear="-2"'), ('polycoef="0 2 0 0 0"', 'polycoef="0 0.5 0 0 0"')],
                         ids=["gear sign", "inverted coupling ratio"])
def test_a_wrong_gear_sign_or_coupling_ratio_is_caught(tmp_path, edit):
    text = (FIXTURES / "coupled_joints.xml").read_text()
    assert edit[0] in text
    (tmp_path / "mutated.xml").write_text(text.replace(*edit))
    result, _ = _contact_free(tmp_path / "mutated.xml")
    _, reference = _contact_free(FIXTURES / "coupled_joints.xml")
    errors = _replay(result, result.model, _fixture_ctrl, 2.0, reference=reference)
    assert errors.max() > 10 * COUPLING_TOLERANCE


def _closing(actuator: int, start: float, end: float, steps: int):
    def ctrl_at(step, data):
        ctrl = data.ctrl.copy()
        ctrl[actuator] = start + (end - start) * min(1.0, step / (steps / 2))
        return ctrl

    return ctrl_at


@needs_menagerie
def test_panda_finger_tendon_and_equality_hold_while_closing():
    result, model = _contact_free(menagerie_root() / "franka_emika_panda/panda.xml")
    assert [e.kind for e in result.equalities] == ["fixed tendon"]
    errors = _replay(result, model, _closing(7, 255.0, 0.0, 500), 1.0)
    assert errors.max() < GRIPPER_TOLERANCE, errors.max()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos[-1] < 0.005 and abs(qpos[-1] - qpos[-2]) < 1e-4  # closed, both fingers together


@needs_menagerie
def test_robotiq_2f85_linkage_holds_while_closing():
    result, model = _contact_free(menagerie_root() / "robotiq_2f85_v4/2f85.xml")
    assert sorted(e.kind for e in result.equalities) == ["D6 joint", "D6 joint", "fixed tendon"]
    errors = _replay(result, model, _closing(0, 0.0, 255.0, 500), 1.0)
    assert errors.max() < GRIPPER_TOLERANCE, errors.max()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos.min() > 0.8  # closed: every joint of the linkage moved with the driver


@needs_menagerie
@pytest.mark.parametrize("relative", ["aloha/scene.xml", "boston_dynamics_spot/spot.xml",
                                      "franka_emika_panda/panda.xml", "google_barkour_vb/barkour_vb.xml",
                                      "leap_hand/right_hand.xml", "robotiq_2f85_v4/2f85.xml",
                                      "tetheria_aero_hand_open/right_hand.xml", "unitree_go1/go1.xml"])
def test_every_menagerie_actuator_is_mapped_or_listed_with_its_reason(relative):
    result = MJCFLoader().load(menagerie_root() / relative)
    assert len(result.actuators) == result.model.nu
    dropped = {e.name: e.reason for e in result.unsupported if e.kind == "actuator"}
    for actuator in result.actuators:
        assert actuator.mapped or dropped[actuator.name] == actuator.reason


def test_single_joint_equality_holds_the_joint_at_qpos0_plus_c0(tmp_path):
    """MuJoCo's joint equality couples displacements from qpos0: alone, it holds q at qpos0 + c0 (ref = 30 deg)."""
    (tmp_path / "held.xml").write_text(
        '<mujoco><compiler angle="degree"/><option gravity="0 0 0"/><worldbody><body>'
        '<joint name="a" axis="0 0 1" ref="30"/><geom size=".1" pos=".2 0 0"/></body></worldbody>'
        '<equality><joint joint1="a" polycoef="0.2 0 0 0 0"/></equality></mujoco>'
    )
    result, model = _contact_free(tmp_path / "held.xml")
    for _ in range(2000):
        result.scene.step()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos[0] == pytest.approx(model.qpos0[0] + 0.2, abs=1e-3)


CLAMPED = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="upper"><joint name="shoulder" axis="0 1 0" damping="0.5" {joint_range}/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03" mass="1"/>
      <body name="lower" pos=".3 0 0"><joint name="elbow" axis="0 1 0" damping="0.2"/>
        <geom type="capsule" fromto="0 0 0 .25 0 0" size=".025" mass=".5"/></body></body>
  </worldbody>
  <actuator>
    <position name="shoulder" joint="shoulder" kp="200" kv="10" {forcerange}/>
    <position name="shoulder_assist" joint="shoulder" kp="20"/>
    <motor name="elbow" joint="elbow" gear="2" ctrlrange="-1 1" forcerange="-0.4 0.4"/>
  </actuator>
</mujoco>"""
CLAMP_TOLERANCE = 2e-5  # rad over 1 s, measured 1.1e-6 (forcerange), 5.9e-6 (actuatorfrcrange; float32 state)


def _clamping_ctrl(step, data):
    return np.array([0.8 * np.sin(step * 0.01), 0.8 * np.sin(step * 0.01), np.sign(np.sin(step * 0.02))])


@pytest.mark.parametrize("limits", [{"forcerange": 'forcerange="-3 3"', "joint_range": ""},
                                    {"forcerange": "", "joint_range": 'actuatorfrcrange="-4 4"'}],
                         ids=["actuator forcerange", "joint actuatorfrcrange"])
def test_clamped_actuator_forces_match_mujoco(tmp_path, limits, monkeypatch):
    """Servos driven far into their force limits (forcerange, or the joint's actuatorfrcrange): MuJoCo clamps the
    explicit actuator force and drops a saturated actuator's kv from its implicit step; the loader applies the
    same clamped force on those steps. Without that (drive force limits alone) the error is over 1e-2."""
    path = tmp_path / "clamped.xml"
    path.write_text(CLAMPED.format(**limits))
    result, model = _contact_free(path)
    data = mujoco.MjData(model)
    saturated = 0
    for step in range(200):
        data.ctrl[:] = _clamping_ctrl(step, data)
        mujoco.mj_forward(model, data)
        saturated += bool(np.abs(data.qfrc_actuator[0]) >= 2.999 if limits["forcerange"] else
                          np.abs(data.qfrc_actuator[0]) >= 3.999)
        mujoco.mj_step(model, data)
    assert saturated > 50  # the run really sits on the limit
    errors = _replay(result, model, _clamping_ctrl, 1.0)
    assert errors.max() < CLAMP_TOLERANCE, errors.max()
    from loader.runtime.actuators import ActuatorTerm

    monkeypatch.setattr(ActuatorTerm, "clamped_step", lambda *args: None)  # the mutation: no explicit clamp
    unclamped, model = _contact_free(path)
    assert _replay(unclamped, model, _clamping_ctrl, 1.0).max() > 100 * CLAMP_TOLERANCE


PASSIVE_TENDON = """<mujoco><option timestep="0.002" gravity="0 0 0" integrator="{integrator}"/>
  <worldbody><body name="base">
    <body name="a"><joint name="a" axis="0 0 1" damping="0.01"/>
      <geom type="box" size=".1 .02 .02" pos=".1 0 0" mass=".5"/></body>
    <body name="b" pos="0 .5 0"><joint name="b" axis="0 0 1"/>
      <geom type="box" size=".15 .02 .02" pos=".15 0 0" mass=".8"/></body>
    <body name="c" pos="0 1 0"><joint name="c" axis="0 0 1"/>
      <geom type="box" size=".1 .02 .02" pos=".1 0 0" mass=".3"/></body>
  </body></worldbody>
  <tendon><fixed name="t" stiffness="0.4" damping="0.05">
    <joint joint="a" coef="1"/><joint joint="b" coef="-0.5"/><joint joint="c" coef="0.5"/></fixed></tendon>
  <keyframe><key qpos="0.4 -0.3 0.2" qvel="1 0 -2"/></keyframe>
</mujoco>"""
TENDON_TOLERANCE = 1e-5  # rad over 1 s, measured 4.2e-7 (implicitfast), 4.0e-7 (Euler); the mutations 2.3e-3


@pytest.mark.parametrize("integrator", ["implicitfast", "Euler"])
def test_a_passive_fixed_tendon_matches_mujoco(tmp_path, monkeypatch, integrator):
    """A tendon spring-damper over three hinges (coefficients 1, -0.5, 0.5): MuJoCo's implicit integrators treat
    the tendon's damping implicitly through its diagonal only, Euler explicitly; the loader follows the model's
    integrator. The mutation (the other treatment) must fail."""
    path = tmp_path / "tendon.xml"
    path.write_text(PASSIVE_TENDON.format(integrator=integrator))

    def load():
        result, model = _contact_free(path)
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER if integrator == "Euler" else model.opt.integrator
        return result, model

    result, model = load()
    assert len(result.controller.term("tendons").tendons) == 1
    errors = _replay(result, model, lambda step, data: np.zeros(0), 1.0)
    assert errors.max() < TENDON_TOLERANCE, errors.max()
    import loader.runtime.controller

    implicit = (int(mujoco.mjtIntegrator.mjINT_EULER),) if integrator == "Euler" else ()
    monkeypatch.setattr(loader.runtime.controller, "IMPLICIT", implicit)  # set_ctrl reads the integrator rule there
    other, model = load()
    assert _replay(other, model, lambda step, data: np.zeros(0), 1.0).max() > 10 * TENDON_TOLERANCE


TENDON_SERVO = """<mujoco><option timestep="0.002" gravity="0 0 -9.81" integrator="implicitfast"/>
  <worldbody><body name="base">
    <body name="a"><joint name="a" axis="0 1 0" damping="0.02"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".015" mass=".05"/></body>
    <body name="b" pos="0 .3 0"><joint name="b" axis="0 1 0" damping="0.02"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".015" mass=".05"/></body>
  </body></worldbody>
  <tendon><fixed name="split"><joint joint="a" coef="0.5"/><joint joint="b" coef="0.5"/></fixed></tendon>
  <actuator><general name="servo" tendon="split" gainprm="2" biastype="affine" biasprm="0 -2 -0.2"
    ctrlrange="-1 1" {forcerange}/></actuator>
</mujoco>"""


@pytest.mark.parametrize("forcerange", ["", 'forcerange="-0.15 0.15"'], ids=["free", "saturating"])
def test_a_tendon_servo_matches_mujoco(tmp_path, monkeypatch, forcerange):
    """A position-like servo on a fixed tendon (the panda's finger "split"): its kv is implicit in MuJoCo through
    the diagonal of kv J^T J only, which the loader puts into the drives; a saturated one is explicit. Over 1 s of
    a square-wave ctrl: 3.5e-7 rad (4.0e-7 saturating); the mutation (kv all explicit) 1e-2 (1.9e-3)."""
    path = tmp_path / "tendon_servo.xml"
    path.write_text(TENDON_SERVO.format(forcerange=forcerange))

    def square(step, data):
        return np.array([0.8 if (step // 100) % 2 else -0.8])

    result, model = _contact_free(path)
    errors = _replay(result, model, square, 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    from loader.runtime.actuators import ActuatorTerm

    monkeypatch.setattr(ActuatorTerm, "implicit_tendon_kv", staticmethod(lambda actuator, saturated: 0.0))
    explicit, model = _contact_free(path)
    assert _replay(explicit, model, square, 1.0).max() > 10 * SERVO_TOLERANCE


FRICTIONAL = """<mujoco><option timestep="0.002" integrator="implicitfast"/>
  <worldbody><body name="base">
    <body name="upper" pos="0 0 1"><joint name="upper" axis="0 1 0" frictionloss="{upper}"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
      <body name="lower" pos=".3 0 0"><joint name="lower" axis="0 1 0" frictionloss="{lower}"/>
        <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body></body>
    <body name="damped" pos="0 1 0"><joint name="damped" axis="0 1 0" damping=".1" frictionloss=".1"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body>
  </body></worldbody>
  <keyframe><key qpos="0.3 -0.5 0"/></keyframe>
</mujoco>"""
FRICTION_TOLERANCE = 1e-5  # rad over 1 s; measured 1.3e-6 sliding, 3.6e-7 sticking (dropped: 0.93, 2.6)


@pytest.mark.parametrize("friction", [{"upper": 0.3, "lower": 0.05}, {"upper": 2.0, "lower": 1.0}],
                         ids=["sliding", "sticking"])
def test_frictionloss_matches_mujoco_on_free_and_damped_joints(tmp_path, friction):
    """A two-link pendulum falling against joint frictionloss (sliding, or mostly stuck) and a damped frictional
    hinge beside it: a PhysX drive (damping s/(R dt), velocity target v (1 - B dt/s), force limit F) solves
    MuJoCo's friction rows, the damped joint's damping riding as armature. Mutation: friction dropped."""
    path = tmp_path / "frictional.xml"
    path.write_text(FRICTIONAL.format(**friction))
    result, model = _contact_free(path)
    listed = {(entry.kind, entry.name) for entry in result.unsupported + result.approximations}
    assert not listed & {("joint", "damped"), ("joint", "upper"), ("joint", "lower")}, listed
    errors = _replay(result, model, lambda step, data: np.zeros(0), 1.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()
    dropped, model = _contact_free(path)
    dropped.controller.without("friction")
    assert _replay(dropped, model, lambda step, data: np.zeros(0), 1.0).max() > 1e3 * FRICTION_TOLERANCE


SERVO_FRICTION = """<mujoco><option timestep="0.002" integrator="implicitfast"/>
  <worldbody><body name="base"><body name="link" pos="0 0 1">
    <joint name="hinge" axis="0 1 0" damping="{damping}" frictionloss="{friction}" armature="0.001"/>
    <geom type="capsule" fromto="0 0 0 .1 0 0" size=".01" mass=".05"/></body></body></worldbody>
  <actuator><position joint="hinge" kp="2" kv="{kv}" ctrlrange="-1 1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize("damping, kv, friction", [(0.1, 0.0, 0.5), (0.1, 0.05, 0.5), (0.0, 0.05, 0.01)],
                         ids=["damped", "damped-servo-kv", "servo-kv"])
def test_frictionloss_on_a_damped_servo_joint_matches_mujoco(tmp_path, monkeypatch, damping, kv, friction):
    """A servo on a damped frictional hinge, stepping between random targets: the drive carries the friction, the
    damping and kv ride as armature dt D with the explicit force -D v, kp as an explicit force; the friction drive
    is scaled by s = 1 + (M^-1)_ii dt D for MuJoCo's friction row, which sees M alone (measured 2.5e-7..3e-7 rad
    over 2 s). Mutation: s = 1 (the friction row solved with PhysX's M + dt D): 5e-4..6.7e-3."""
    path = tmp_path / "servo_friction.xml"
    path.write_text(SERVO_FRICTION.format(damping=damping, kv=kv, friction=friction))
    targets = np.random.default_rng(0).uniform(-1, 1, (20, 1))
    result, model = _contact_free(path)
    assert not {(e.kind, e.name) for e in result.unsupported + result.approximations} & {("joint", "hinge")}
    errors = _replay(result, model, lambda step, data: targets[step // 50], 2.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()
    from loader.runtime.friction import FrictionRow

    monkeypatch.setattr(FrictionRow, "scale", lambda self, implicit_damping, timestep: 1.0)
    unscaled, model = _contact_free(path)
    assert _replay(unscaled, model, lambda step, data: targets[step // 50], 2.0).max() > 10 * FRICTION_TOLERANCE


@pytest.mark.parametrize("forcerange", ["", 'forcerange="-0.3 0.3"'], ids=["free", "saturating"])
def test_a_motor_on_a_frictional_joint_keeps_its_force(tmp_path, forcerange):
    """A plain motor adds no gains, so the joint's drive still carries the frictionloss; the motor's force must
    still reach the joint (explicit, as MuJoCo's a0 holds it), clamped or not (the clamped steps once dropped the
    friction: 0.73 rad)."""
    text = FRICTIONAL.format(upper=0.3, lower=0.05).replace(
        "</worldbody>", f'</worldbody><actuator><motor joint="upper" gear="2" ctrlrange="-1 1" {forcerange}/>'
        '</actuator>')
    path = tmp_path / "motor.xml"
    path.write_text(text)
    result, model = _contact_free(path)
    assert ("joint", "upper") not in {(e.kind, e.name) for e in result.unsupported + result.approximations}
    errors = _replay(result, model, lambda step, data: np.array([np.sin(step * 0.02)]), 1.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()


SERVO_ARM = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><body name="upper" pos="0 0 1"><joint name="shoulder" axis="0 1 0" damping="{damping}"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
    <body name="lower" pos=".3 0 0"><joint name="elbow" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body></body></worldbody>
  <actuator><position joint="shoulder" kp="{kp}" kv="{kv}" ctrlrange="-1 1"/>
    <position joint="elbow" kp="5" kv="0.2" ctrlrange="-1 1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize("integrator, damping, kp, kv", [
    ("Euler", 0.1, 20, 0.5),  # kv explicit, kp in the drive (the passive damping absorbs kp dt)
    ("Euler", 0.0, 20, 0.5),  # kv and kp explicit (no implicit damping left for kp)
    ("implicitfast", 0.0, 200, 0.1),  # kv implicit, kp explicit: kv < kp dt
], ids=["euler-kp-in-drive", "euler-kp-explicit", "implicitfast-kp-explicit"])
def test_servo_gains_follow_the_models_integrator(tmp_path, integrator, damping, kp, kv):
    """Under Euler MuJoCo applies kv explicitly, under implicitfast implicitly; kp is always explicit. The loader
    follows the model's integrator (measured 5.6e-7, 8.9e-7, 1.9e-6 rad over 1 s). Mutation: the SAPIEN side told
    the other integrator while MuJoCo keeps the model's (3.2e-2, 3.4e-2, 0.15)."""
    path = tmp_path / "servo_arm.xml"
    path.write_text(SERVO_ARM.format(integrator=integrator, damping=damping, kp=kp, kv=kv))
    targets = np.random.default_rng(1).uniform(-1, 1, (10, 2))
    result = MJCFLoader().load(path)
    model = result.model
    assert not result.approximations, result.approximations
    errors = _replay(result, model, lambda step, data: targets[step // 50], 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    other = MJCFLoader().load(path)
    reference = copy.deepcopy(other.model)
    flipped = "IMPLICITFAST" if integrator == "Euler" else "EULER"
    other.model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{flipped}")
    assert _replay(other, other.model, lambda step, data: targets[step // 50], 1.0,
                   reference=reference).max() > 10 * SERVO_TOLERANCE


ACTIVATED = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody>
    <body pos="0 0 1"><joint name="a" axis="0 1 0" damping="0.02"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body>
    <body pos="0 1 1"><joint name="b" axis="0 1 0" damping="0.02"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body>
    <body pos="0 2 1"><joint name="c" axis="0 1 0" damping="0.02"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body>
    <body pos="0 3 1"><joint name="d" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body>
  </worldbody>
  <actuator>
    <general joint="a" dyntype="filter" dynprm="0.05" gainprm="0.5" ctrlrange="-1 1"/>
    <general joint="b" dyntype="filterexact" dynprm="0.01" gainprm="0.5" ctrlrange="-1 1" actearly="true"/>
    <general joint="c" dyntype="integrator" gainprm="0.5" ctrlrange="-1 1" actlimited="true" actrange="-0.3 0.4"/>
    <general joint="d" dyntype="filter" dynprm="0.03" gainprm="3" biastype="affine" biasprm="0 -3 -0.1"
             ctrlrange="-1 1"/>
  </actuator>
  <keyframe><key qpos="0 0 0 0" act="0.2 -0.1 0.3 0.5" ctrl="0 0 0 0"/></keyframe>
</mujoco>"""


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_activation_dynamics_match_mujoco(tmp_path, monkeypatch, integrator):
    """filter, filterexact with actearly, a limited integrator and a filtered position servo: the loader steps the
    activation as MuJoCo does and feeds it to the force law (from the keyframe's act, under random ctrl steps).
    Measured: act equal to MuJoCo's bit for bit, qpos 1.3e-6 rad over 1 s. Mutation: the gain fed ctrl instead of
    the activation (1.4 rad)."""
    path = tmp_path / "activated.xml"
    path.write_text(ACTIVATED.format(integrator=integrator))
    targets = np.random.default_rng(2).uniform(-1, 1, (10, 4))
    result = MJCFLoader().load(path)
    assert all(a.mapped for a in result.actuators), [a.reason for a in result.actuators]
    assert [a.dynamics for a in result.actuators] == ["filter", "filterexact", "integrator", "filter"]
    errors = _replay(result, result.model, lambda step, data: targets[step // 50], 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    from loader.runtime.activation import Activation

    monkeypatch.setattr(Activation, "inputs", lambda self, ctrl: np.asarray(ctrl, dtype=float).copy())
    blind = MJCFLoader().load(path)
    assert _replay(blind, blind.model, lambda step, data: targets[step // 50], 1.0).max() > 10 * SERVO_TOLERANCE


def test_step_holds_the_ctrl_over_substeps_with_every_step_s_terms(tmp_path):
    """result.step(ctrl, substeps=n) equals MuJoCo with the ctrl held for n steps, on a damped frictional servo
    hinge (whose kp and damping the loader writes as per-step forces): 4.5e-8 rad over 10 targets of 25 steps.
    Mutation: set_ctrl once, then n bare scene.step() calls (the forces of the first step frozen): 220 rad."""
    path = tmp_path / "servo_friction.xml"
    path.write_text(SERVO_FRICTION.format(damping=0.1, kv=0.05, friction=0.05))
    targets = np.random.default_rng(3).uniform(-1, 1, (10, 1))

    def run(held: bool) -> float:
        result = MJCFLoader().load(path)
        model = result.model
        data = mujoco.MjData(model)
        result.reset()
        worst = 0.0
        for target in targets:
            data.ctrl[:] = target
            for _ in range(25):
                mujoco.mj_step(model, data)
            if held:
                result.step(target, substeps=25)
            else:
                result.set_ctrl(target)
                for _ in range(25):
                    result.scene.step()
            worst = max(worst, float(np.abs(result.mapping.get_state(result.articulations)[0] - data.qpos).max()))
        return worst

    assert run(held=True) < FRICTION_TOLERANCE
    assert run(held=False) > 10 * FRICTION_TOLERANCE


def test_release_leaves_passive_drives_that_need_no_set_ctrl(tmp_path):
    """After result.release(), bare scene.step() calls simulate the joints' passive spring-dampers exactly (MuJoCo
    with its actuators off and without the frictionloss the drives no longer carry): 2.3e-8 rad over 1 s. Mutation:
    no release, so the frictional joint keeps armature dt*D without the force that goes with it: 0.37 rad."""
    path = tmp_path / "servo_friction.xml"
    path.write_text(SERVO_FRICTION.format(damping=0.5, kv=0.05, friction=0.05))

    def run(release: bool) -> float:
        result = MJCFLoader().load(path)
        reference = copy.deepcopy(result.model)
        reference.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION
        reference.dof_frictionloss[:] = 0.0
        data = mujoco.MjData(reference)
        data.qvel[:] = 3.0
        result.mapping.set_state(result.articulations, data.qpos.copy(), data.qvel.copy())
        if release:
            result.release()
        worst = 0.0
        for _ in range(500):
            mujoco.mj_step(reference, data)
            result.scene.step()
            worst = max(worst, float(np.abs(result.mapping.get_state(result.articulations)[0] - data.qpos).max()))
        return worst

    assert run(release=True) < SERVO_TOLERANCE
    assert run(release=False) > 10 * SERVO_TOLERANCE


FLUID = """<mujoco><option timestep="0.002" integrator="Euler" density="{density}" viscosity="{viscosity}"
  wind="{wind}" gravity="0 0 0"/>
  <worldbody><body name="blade" pos="0 0 1"><joint name="hinge" axis="0 1 0"/>
    <geom type="box" size=".2 .05 .1" pos=".3 0 0" euler="0 20 10" mass="1"/></body></worldbody>
</mujoco>"""


@pytest.mark.parametrize("density, viscosity, wind", [(1000, 0, "0 0 0"), (0, 0.5, "0 0 0"), (1200, 0.1, "1 -2 0")],
                         ids=["drag", "viscous", "both-with-wind"])
def test_fluid_forces_match_mujoco(tmp_path, density, viscosity, wind):
    """A blade spinning on a hinge through MuJoCo's inertia-box fluid: the loader's per-step link forces equal
    MuJoCo's qfrc_fluid (one step from 2 rad/s: 4e-8 rad/s on a 4e-2 change). Mutation: fluid dropped."""
    path = tmp_path / "fluid.xml"
    path.write_text(FLUID.format(density=density, viscosity=viscosity, wind=wind))

    def one_step(keep: bool) -> float:
        result = MJCFLoader().load(path)
        if not keep:
            result.controller.without("fluid")
        data = mujoco.MjData(result.model)
        data.qvel[:] = 2.0
        result.mapping.set_state(result.articulations, data.qpos.copy(), data.qvel.copy())
        result.set_ctrl(None)
        mujoco.mj_step(result.model, data)
        result.scene.step()
        return float(np.abs(result.mapping.get_state(result.articulations)[1] - data.qvel).max())

    assert one_step(keep=True) < 1e-6
    assert one_step(keep=False) > 1e-4


GRAVCOMP = """<mujoco><option timestep="0.002"/>
  <worldbody><body name="upper" pos="0 0 1" gravcomp="{upper}"><joint name="shoulder" axis="0 1 0" damping="0.05"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
    <body name="lower" pos=".3 0 0" gravcomp="{lower}"><joint name="elbow" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body></body></worldbody>
</mujoco>"""


@pytest.mark.parametrize("upper, lower", [(1, 1), (0.5, 1), (1, 1.5)], ids=["full", "half", "over"])
def test_gravity_compensation_matches_mujoco(tmp_path, monkeypatch, upper, lower):
    """An arm whose links compensate gravity fully (PhysX gravity off for the link), partly or more than fully
    (a per-step force at the centre of mass): 1.6e-15, 1.5e-6, 8.7e-7 rad over 1 s. Mutation: the loader ignoring
    gravcomp (the arm falls)."""
    path = tmp_path / "gravcomp.xml"
    path.write_text(GRAVCOMP.format(upper=upper, lower=lower))
    result = MJCFLoader().load(path)
    assert _replay(result, result.model, lambda step, data: np.zeros(0), 1.0).max() < SERVO_TOLERANCE
    import loader.runtime.controller

    monkeypatch.setattr(loader.runtime.controller, "map_gravcomp", lambda *args: None)  # planned at load
    ignored = MJCFLoader().load(path)
    assert _replay(ignored, ignored.model, lambda step, data: np.zeros(0), 1.0).max() > 10 * SERVO_TOLERANCE


@pytest.mark.parametrize("flags", ['spring="disable"', 'damper="disable"', 'spring="disable" damper="disable"'])
def test_spring_and_damper_flags_are_honoured(tmp_path, monkeypatch, flags):
    """<flag spring/damper="disable"/> turns joint and tendon springs/dampers off in MuJoCo; the loader too.
    Mutation: flags ignored (the springs and dampers mapped anyway)."""
    path = tmp_path / "flags.xml"
    path.write_text(f"""<mujoco><option timestep="0.002"><flag {flags}/></option>
      <worldbody><body pos="0 0 1"><joint name="a" axis="0 1 0" stiffness="3" springref="0.5" damping="0.2"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/></body>
        <body pos="0 1 1"><joint name="b" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"
          mass=".5"/></body></worldbody>
      <tendon><fixed stiffness="2" damping="0.3"><joint joint="a" coef="1"/><joint joint="b" coef="-1"/></fixed>
      </tendon></mujoco>""")
    result = MJCFLoader().load(path)
    assert _replay(result, result.model, lambda step, data: np.zeros(0), 1.0).max() < SERVO_TOLERANCE
    import loader.mj

    monkeypatch.setattr(loader.mj, "disabled", lambda model, *flags: False)  # the fixture sets no other flag
    blind = MJCFLoader().load(path)
    assert _replay(blind, blind.model, lambda step, data: np.zeros(0), 1.0).max() > 10 * SERVO_TOLERANCE
