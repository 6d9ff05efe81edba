"""Actuators: servos, motors and general actuators under the same ctrl on both sides; MuJoCo is the oracle.

Contact is off on both sides and MuJoCo integrates with the model's integrator (implicitfast for the Menagerie
arms). Each test has a deliberate mistake that must fail.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest
from support.corpus import MENAGERIE, menagerie_root, mjcf_file
from support.lockstep import contact_free, paired_rollout, replay
from test_loader_friction import FRICTION_TOLERANCE, SERVO_FRICTION

from loader import MJCFLoader

SERVO_TOLERANCE = 2e-5  # rad, measured 3e-6


needs_menagerie = pytest.mark.skipif(menagerie_root() is None, reason="Menagerie slice not installed")


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
    result, model = contact_free(menagerie_root() / "franka_emika_panda/panda.xml")
    assert all(a.mapped for a in result.actuators)
    errors = replay(result, model, _small_steps(model), 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()


@needs_menagerie
def test_a_five_percent_kp_error_is_caught():
    def mutate(result):
        for drive in result.controller.edit_laws().values():
            if drive.stiffness > 0:
                drive.stiffness *= 1.05

    result, model = contact_free(menagerie_root() / "franka_emika_panda/panda.xml", mutate)
    errors = replay(result, model, _small_steps(model), 1.0)
    assert errors.max() > SERVO_TOLERANCE


@needs_menagerie
@pytest.mark.parametrize("relative", MENAGERIE)
def test_every_menagerie_actuator_is_mapped_or_listed_with_its_reason(relative):
    result = MJCFLoader().load(menagerie_root() / relative)
    assert len(result.actuators) == result.model.nu
    dropped = {e.name: e.reason for e in result.unsupported if e.kind == "actuator"}
    for actuator in result.actuators:
        assert actuator.mapped or dropped[actuator.name] == actuator.reason


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


@pytest.mark.parametrize(
    "limits",
    [
        {"forcerange": 'forcerange="-3 3"', "joint_range": ""},
        {"forcerange": "", "joint_range": 'actuatorfrcrange="-4 4"'},
    ],
    ids=["actuator forcerange", "joint actuatorfrcrange"],
)
@pytest.mark.usefixtures("terms")
def test_clamped_actuator_forces_match_mujoco(tmp_path, limits, monkeypatch):
    """Servos driven far into their force limits (forcerange, or the joint's actuatorfrcrange): MuJoCo clamps the
    explicit actuator force and drops a saturated actuator's kv from its implicit step; the loader applies the
    same clamped force on those steps. Without that (drive force limits alone) the error is over 1e-2."""
    path = mjcf_file(tmp_path, CLAMPED.format(**limits), "clamped.xml")
    result, model = contact_free(path)
    data = mujoco.MjData(model)
    saturated = 0
    for step in range(200):
        data.ctrl[:] = _clamping_ctrl(step, data)
        mujoco.mj_forward(model, data)
        saturated += bool(
            np.abs(data.qfrc_actuator[0]) >= 2.999 if limits["forcerange"] else np.abs(data.qfrc_actuator[0]) >= 3.999
        )
        mujoco.mj_step(model, data)
    assert saturated > 50  # the run really sits on the limit
    errors = replay(result, model, _clamping_ctrl, 1.0)
    assert errors.max() < CLAMP_TOLERANCE, errors.max()
    from loader.runtime.actuators import ActuatorTerm

    monkeypatch.setattr(ActuatorTerm, "clamped_step", lambda *args: None)  # the mutation: no explicit clamp
    unclamped, model = contact_free(path)
    assert replay(unclamped, model, _clamping_ctrl, 1.0).max() > 100 * CLAMP_TOLERANCE


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


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("forcerange", ["", 'forcerange="-0.15 0.15"'], ids=["free", "saturating"])
def test_a_tendon_servo_matches_mujoco(tmp_path, monkeypatch, forcerange):
    """A position-like servo on a fixed tendon (the panda's finger "split"): its kv is implicit in MuJoCo through
    the diagonal of kv J^T J only, which the loader puts into the drives; a saturated one is explicit. Over 1 s of
    a square-wave ctrl: 3.5e-7 rad (4.0e-7 saturating); the mutation (kv all explicit) 1e-2 (1.9e-3)."""
    path = mjcf_file(tmp_path, TENDON_SERVO.format(forcerange=forcerange), "tendon_servo.xml")

    def square(step, data):
        return np.array([0.8 if (step // 100) % 2 else -0.8])

    result, model = contact_free(path)
    errors = replay(result, model, square, 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    from loader.runtime.actuators import ActuatorTerm

    monkeypatch.setattr(ActuatorTerm, "implicit_tendon_kv", staticmethod(lambda actuator, saturated: 0.0))
    explicit, model = contact_free(path)
    assert replay(explicit, model, square, 1.0).max() > 10 * SERVO_TOLERANCE


SERVO_ARM = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><body name="upper" pos="0 0 1"><joint name="shoulder" axis="0 1 0" damping="{damping}"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
    <body name="lower" pos=".3 0 0"><joint name="elbow" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body></body></worldbody>
  <actuator><position joint="shoulder" kp="{kp}" kv="{kv}" ctrlrange="-1 1"/>
    <position joint="elbow" kp="5" kv="0.2" ctrlrange="-1 1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize(
    "integrator, damping, kp, kv",
    [
        ("Euler", 0.1, 20, 0.5),  # kv explicit, kp in the drive (the passive damping absorbs kp dt)
        ("Euler", 0.0, 20, 0.5),  # kv and kp explicit (no implicit damping left for kp)
        ("implicitfast", 0.0, 200, 0.1),  # kv implicit, kp explicit: kv < kp dt
    ],
    ids=["euler-kp-in-drive", "euler-kp-explicit", "implicitfast-kp-explicit"],
)
def test_servo_gains_follow_the_models_integrator(tmp_path, integrator, damping, kp, kv):
    """Under Euler MuJoCo applies kv explicitly, under implicitfast implicitly; kp is always explicit. The loader
    follows the model's integrator (measured 5.6e-7, 8.9e-7, 1.9e-6 rad over 1 s). Mutation: the SAPIEN side told
    the other integrator while MuJoCo keeps the model's (3.2e-2, 3.4e-2, 0.15)."""
    path = mjcf_file(tmp_path, SERVO_ARM.format(integrator=integrator, damping=damping, kp=kp, kv=kv), "servo_arm.xml")
    targets = np.random.default_rng(1).uniform(-1, 1, (10, 2))
    result = MJCFLoader().load(path)
    model = result.model
    assert not result.approximations, result.approximations
    errors = replay(result, model, lambda step, data: targets[step // 50], 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    other = MJCFLoader().load(path)
    reference = copy.deepcopy(other.model)
    flipped = "IMPLICITFAST" if integrator == "Euler" else "EULER"
    other.model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{flipped}")
    other.replan()  # the edit reaches the steps only now
    assert (
        replay(other, other.model, lambda step, data: targets[step // 50], 1.0, reference=reference).max()
        > 10 * SERVO_TOLERANCE
    )


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


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_activation_dynamics_match_mujoco(tmp_path, monkeypatch, integrator):
    """filter, filterexact with actearly, a limited integrator and a filtered position servo: the loader steps the
    activation as MuJoCo does and feeds it to the force law (from the keyframe's act, under random ctrl steps).
    Measured: act equal to MuJoCo's bit for bit, qpos 1.3e-6 rad over 1 s. Mutation: the gain fed ctrl instead of
    the activation (1.4 rad)."""
    path = mjcf_file(tmp_path, ACTIVATED.format(integrator=integrator), "activated.xml")
    targets = np.random.default_rng(2).uniform(-1, 1, (10, 4))
    result = MJCFLoader().load(path)
    assert all(a.mapped for a in result.actuators), [a.reason for a in result.actuators]
    assert [a.dynamics for a in result.actuators] == ["filter", "filterexact", "integrator", "filter"]
    errors = replay(result, result.model, lambda step, data: targets[step // 50], 1.0)
    assert errors.max() < SERVO_TOLERANCE, errors.max()
    from loader.runtime.activation import Activation

    monkeypatch.setattr(Activation, "inputs", lambda self, ctrl: np.asarray(ctrl, dtype=float).copy())
    blind = MJCFLoader().load(path)
    assert replay(blind, blind.model, lambda step, data: targets[step // 50], 1.0).max() > 10 * SERVO_TOLERANCE


def test_step_holds_the_ctrl_over_substeps_with_every_step_s_terms(tmp_path):
    """result.step(ctrl, substeps=n) equals MuJoCo with the ctrl held for n steps, on a damped frictional servo
    hinge (whose friction rows set_ctrl writes as per-step forces). Mutation: set_ctrl once, then n bare
    scene.step() calls (the friction force of the first step frozen)."""
    path = mjcf_file(tmp_path, SERVO_FRICTION.format(damping=0.1, kv=0.05, friction=0.3), "servo_friction.xml")
    targets = np.random.default_rng(3).uniform(-1, 1, (10, 1))

    def run(held: bool) -> float:
        """MuJoCo holds each target over 25 steps; SAPIEN is driven by `step` or by one set_ctrl (not lockstep:
        what is compared is the public call's substepping)."""
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
    path = mjcf_file(tmp_path, SERVO_FRICTION.format(damping=0.5, kv=0.05, friction=0.05), "servo_friction.xml")

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
        return float(paired_rollout(result, reference, data, 500, set_ctrl=False).qpos.max())

    assert run(release=True) < SERVO_TOLERANCE
    assert run(release=False) > 10 * SERVO_TOLERANCE
