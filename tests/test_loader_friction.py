"""Joint frictionloss: MuJoCo's friction rows carried by the joints' drives (docs/mapping.md#frictionloss)."""

from __future__ import annotations

import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import contact_free, no_ctrl, replay

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


@pytest.mark.parametrize(
    "friction", [{"upper": 0.3, "lower": 0.05}, {"upper": 2.0, "lower": 1.0}], ids=["sliding", "sticking"]
)
def test_frictionloss_matches_mujoco_on_free_and_damped_joints(tmp_path, friction):
    """A two-link pendulum falling against joint frictionloss (sliding, or mostly stuck) and a damped frictional
    hinge beside it: a PhysX drive (damping s/(R dt), velocity target v (1 - B dt/s), force limit F) solves
    MuJoCo's friction rows, the damped joint's damping riding as armature. Mutation: friction dropped."""
    path = mjcf_file(tmp_path, FRICTIONAL.format(**friction), "frictional.xml")
    result, model = contact_free(path)
    listed = {(entry.kind, entry.name) for entry in result.unsupported + result.approximations}
    assert not listed & {("joint", "damped"), ("joint", "upper"), ("joint", "lower")}, listed
    errors = replay(result, model, no_ctrl, 1.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()
    dropped, model = contact_free(path)
    dropped.controller.without("rows")
    assert replay(dropped, model, no_ctrl, 1.0).max() > 1e3 * FRICTION_TOLERANCE


SERVO_FRICTION = """<mujoco><option timestep="0.002" integrator="implicitfast"/>
  <worldbody><body name="base"><body name="link" pos="0 0 1">
    <joint name="hinge" axis="0 1 0" damping="{damping}" frictionloss="{friction}" armature="0.001"/>
    <geom type="capsule" fromto="0 0 0 .1 0 0" size=".01" mass=".05"/></body></body></worldbody>
  <actuator><position joint="hinge" kp="2" kv="{kv}" ctrlrange="-1 1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize(
    "damping, kv, friction",
    [(0.1, 0.0, 0.5), (0.1, 0.05, 0.5), (0.0, 0.05, 0.01)],
    ids=["damped", "damped-servo-kv", "servo-kv"],
)
def test_frictionloss_on_a_damped_servo_joint_matches_mujoco(tmp_path, monkeypatch, damping, kv, friction):
    """A servo on a damped frictional hinge, stepping between random targets: MuJoCo solves the friction row with
    the servo's force in the unconstrained acceleration, and so must the loader. Mutation: the row solved without
    the servo's force (MuJoCo's copy given no ctrl)."""
    path = mjcf_file(tmp_path, SERVO_FRICTION.format(damping=damping, kv=kv, friction=friction), "servo_friction.xml")
    targets = np.random.default_rng(0).uniform(-1, 1, (20, 1))
    result, model = contact_free(path)
    assert not {(e.kind, e.name) for e in result.unsupported + result.approximations} & {("joint", "hinge")}
    errors = replay(result, model, lambda step, data: targets[step // 50], 2.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()
    from loader.runtime.rows import RowTerm

    original = RowTerm.mirror_state

    def without_ctrl(self, step):
        original(self, step)
        self.data.ctrl[:] = 0.0

    monkeypatch.setattr(RowTerm, "mirror_state", without_ctrl)
    unscaled, model = contact_free(path)
    assert replay(unscaled, model, lambda step, data: targets[step // 50], 2.0).max() > 10 * FRICTION_TOLERANCE


@pytest.mark.parametrize("forcerange", ["", 'forcerange="-0.3 0.3"'], ids=["free", "saturating"])
def test_a_motor_on_a_frictional_joint_keeps_its_force(tmp_path, forcerange):
    """A plain motor adds no gains, so the joint's drive still carries the frictionloss; the motor's force must
    still reach the joint (explicit, as MuJoCo's a0 holds it), clamped or not (the clamped steps once dropped the
    friction: 0.73 rad)."""
    text = FRICTIONAL.format(upper=0.3, lower=0.05).replace(
        "</worldbody>",
        f'</worldbody><actuator><motor joint="upper" gear="2" ctrlrange="-1 1" {forcerange}/></actuator>',
    )
    path = mjcf_file(tmp_path, text, "motor.xml")
    result, model = contact_free(path)
    assert ("joint", "upper") not in {(e.kind, e.name) for e in result.unsupported + result.approximations}
    errors = replay(result, model, lambda step, data: np.array([np.sin(step * 0.02)]), 1.0)
    assert errors.max() < FRICTION_TOLERANCE, errors.max()


FREE_FRICTION = """<mujoco><option timestep="0.002" gravity="0 0 0"/><worldbody>
  <body name="cube" pos="0 0 1"><joint name="root" type="free" frictionloss="0.01"/>
    <geom type="box" size=".05 .04 .03" mass="0.2"/>
    <body name="flap" pos=".05 0 0"><joint name="hinge" axis="0 1 0" damping="0.01"/>
      <geom type="capsule" fromto="0 0 0 .1 0 0" size=".01" mass=".02"/></body></body></worldbody></mujoco>"""
# rad or m over 1 s of a tumbling cube whose free joint has frictionloss, contact off: measured 1.2e-6 (mujoco 3.17.0,
# sapien 3.0.3); the friction rows switched off 0.45
FREE_FRICTION_TOLERANCE = 1e-5


def test_frictionloss_on_a_free_joint_matches_mujoco(tmp_path):
    """MuJoCo's friction rows on a free joint's six DoFs, solved with the others, go on the root link as a wrench
    (`runtime/integrated.py`'s `RootPush`): a cube kicked into a tumble slows as MuJoCo's does."""
    import mujoco
    from support.lockstep import paired_rollout

    from loader import MJCFLoader

    result = MJCFLoader().load(mjcf_file(tmp_path, FREE_FRICTION))
    assert not result.unsupported
    model = result.model
    data = mujoco.MjData(model)
    data.qvel[:] = [0.3, -0.2, 0.1, 1.0, -0.5, 0.8, 0.5]
    result.set_state(data.qpos, data.qvel)
    assert paired_rollout(result, model, data, 500).qpos.max() < FREE_FRICTION_TOLERANCE
    assert np.abs(data.qvel[:6]).max() < 0.3  # the friction took most of the kick


BALL_FRICTION = """<mujoco><option timestep="0.002"/><worldbody>
  <body pos="0 0 1"><joint name="ball" type="ball" frictionloss="{friction}" damping="0.01"/>
    <geom type="capsule" fromto="0 0 0 .3 0.05 -0.1" size=".02" mass=".3"/></body></worldbody>
  <keyframe><key qpos="0.9 0.3 -0.2 0.1" qvel="1.5 -2 1"/></keyframe></mujoco>"""
BALL_FRICTIONLOSS = 0.05  # N m
# relative: the velocity change one step of the ball's frictionloss makes (SAPIEN's with it less SAPIEN's without,
# against MuJoCo's the same way; MuJoCo's 9.4e-3 rad/s), as a share of MuJoCo's. Measured (mujoco 3.17.0, sapien
# 3.0.3): 8.8 %, the ball joint's own approximation (three revolutes in Euler angles); not carried, 100 %
BALL_FRICTION_SHARE = 0.2


def _friction_change(tmp_path) -> tuple[np.ndarray, np.ndarray]:
    """rad/s: the ball joint's velocity after one step with its frictionloss less without, in SAPIEN and MuJoCo."""
    import mujoco

    from loader import MJCFLoader

    ends = []
    for friction in (0.0, BALL_FRICTIONLOSS):
        result = MJCFLoader().load(mjcf_file(tmp_path, BALL_FRICTION.format(friction=friction), "ball.xml"))
        model = result.model
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        result.set_state(data.qpos, data.qvel)
        result.set_ctrl(None)
        result.scene.step()
        mujoco.mj_step(model, data)
        ends.append((result.get_state()[1], data.qvel.copy()))
    (sapien_plain, mujoco_plain), (sapien_rubbing, mujoco_rubbing) = ends
    return sapien_rubbing - sapien_plain, mujoco_rubbing - mujoco_plain


def test_frictionloss_on_a_ball_joint_acts_on_its_angles_as_in_mujoco(tmp_path, monkeypatch):
    """MuJoCo's three friction rows of a ball joint, solved by the rows term, go on SAPIEN's three Euler angles as
    E^T tau (docs/mapping.md#frictionloss). Mutation: the ball's friction taken out of MuJoCo's copy."""
    from loader.runtime import rows

    ours, theirs = _friction_change(tmp_path)
    assert np.abs(ours - theirs).max() < BALL_FRICTION_SHARE * np.abs(theirs).max()
    monkeypatch.setattr(rows, "FRICTIONAL_JOINTS", ("hinge", "slide", "free"))
    lost, theirs = _friction_change(tmp_path)
    assert np.abs(lost - theirs).max() > BALL_FRICTION_SHARE * np.abs(theirs).max()
