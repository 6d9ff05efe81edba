"""Passive spatial tendons: a spring with a dead band and a damper along sites and a wrapping cylinder, carried as
joint forces J^T f from MuJoCo's own length and Jacobian at SAPIEN's pose (loader/runtime/spatial_tendons.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import no_ctrl, replay

from loader import MJCFLoader

FINGER = """<mujoco><option timestep="0.002" gravity="0 0 -9.81" integrator="{integrator}"/>
  <worldbody><site name="anchor" pos="-0.02 0 0.05"/>
    <body name="proximal"><joint name="mcp" axis="0 1 0" range="-0.2 1.6" damping="0.002"/>
      <geom type="capsule" fromto="0 0 0 0.05 0 0" size="0.008" mass="0.02"/>
      <site name="p1" pos="0.02 0 0.01"/>
      <body name="distal" pos="0.05 0 0"><joint name="pip" axis="0 1 0" range="0 1.7"/>
        <geom name="pulley" type="cylinder" fromto="0 -0.005 0 0 0.005 0" size="0.006" mass="0.001"/>
        <geom type="capsule" fromto="0 0 0 0.04 0 0" size="0.007" mass="0.015"/>
        <site name="d1" pos="0.03 0 0.008"/><site name="side" pos="0 0 0.02"/></body></body>
  </worldbody>
  <tendon>
    <spatial name="extensor" stiffness="400" springlength="0.09 0.095" damping="{damping}">
      <site site="anchor"/><site site="p1"/><geom geom="pulley" sidesite="side"/><site site="d1"/></spatial>
    <spatial name="short" stiffness="60" springlength="0.03"><site site="p1"/><site site="d1"/></spatial>
  </tendon>
  <keyframe><key qpos="0.5 0.9" qvel="2 -3"/></keyframe>
</mujoco>"""

SPATIAL_TOLERANCE = 1e-5  # rad over 1 s; measured 7e-7 (Euler), the mutations 6e-3 and more (mujoco 3.17.0,
# sapien 3.0.3)
FLOATING_TOLERANCE = 5e-4  # rad over 0.5 s on a floating palm (the harness's floating rollout tolerance); measured
# 8.6e-5, growing with the springs' stiffness (4.8e-7 without them: the momentum term's step), the mutation 3.3
IMPLICIT_DAMPING = 0.01  # N s/m on a 20 g finger: dt b J^2 / I about 1e-3
IMPLICIT_TOLERANCE = 1e-3  # rad over 1 s with the damper's off-diagonal explicit; measured 4.6e-4, explicit 1.2e-3
# (the error grows linearly in the damping)


def load(tmp_path, integrator: str, damping: float = 0.0):
    path = mjcf_file(tmp_path, FINGER.format(integrator=integrator, damping=damping), "finger.xml")
    result = MJCFLoader().load(path)
    return result, result.model


def test_a_spatial_tendon_spring_matches_mujoco(tmp_path):
    """Euler, springs only: the tendons' forces are MuJoCo's own at every step. Mutation: the tendons' term off."""
    result, model = load(tmp_path, "Euler")
    assert result.controller.term("tendons").spatial is not None
    assert not [n for n in result.unsupported if "tendon" in str(n)]
    errors = replay(result, model, no_ctrl, 1.0)
    assert errors.max() < SPATIAL_TOLERANCE, errors.max()
    result.controller.without("tendons")
    assert replay(result, model, no_ctrl, 1.0).max() > 100 * SPATIAL_TOLERANCE


@pytest.mark.usefixtures("terms")
def test_a_spatial_tendon_damper_under_euler_is_explicit(tmp_path, monkeypatch):
    """Euler takes a tendon damper explicitly, so the step is exact. Mutation: its diagonal made implicit."""
    result, model = load(tmp_path, "Euler", damping=0.05)
    errors = replay(result, model, no_ctrl, 1.0)
    assert errors.max() < SPATIAL_TOLERANCE, errors.max()
    import loader.model.options

    monkeypatch.setattr(loader.model.options, "IMPLICIT", (int(mujoco.mjtIntegrator.mjINT_EULER),))
    other, model = load(tmp_path, "Euler", damping=0.05)
    assert replay(other, model, no_ctrl, 1.0).max() > 10 * SPATIAL_TOLERANCE


def test_a_spatial_tendon_damper_under_implicitfast_is_noted_and_close(tmp_path):
    """MuJoCo's implicitfast holds the whole b J^T J implicitly, the drives its diagonal: an approximation note
    names the tendon and 1 s stays within 1e-3 rad. Mutation: the damper left explicit."""
    result, model = load(tmp_path, "implicitfast", damping=IMPLICIT_DAMPING)
    assert any("extensor" in str(note) and "J^T J" in str(note) for note in result.approximations)
    errors = replay(result, model, no_ctrl, 1.0)
    assert errors.max() < IMPLICIT_TOLERANCE, errors.max()
    other, model = load(tmp_path, "implicitfast", damping=IMPLICIT_DAMPING)
    other.controller.edit("tendons").spatial.implicit = False
    assert replay(other, model, no_ctrl, 1.0).max() > 2 * errors.max()


def floating_finger(tmp_path):
    """The finger on a floating 50 g palm, its tendons anchored on the world, contact-free on both sides."""
    floating = (
        FINGER.format(integrator="Euler", damping=0.02)
        .replace(
            '<site name="anchor" pos="-0.02 0 0.05"/>',
            '<site name="anchor" pos="-0.02 0 0.05"/><body name="palm"><freejoint/>'
            '<geom type="box" size=".02 .03 .01" pos="-.03 0 0" mass="0.05"/>',
        )
        .replace("</worldbody>", "</body></worldbody>")
        .replace('<key qpos="0.5 0.9" qvel="2 -3"/>', '<key qpos="0 0 0 1 0 0 0 0.5 0.9" qvel="0 0 0 0 0 0 2 -3"/>')
    )
    result = MJCFLoader().load(
        mjcf_file(tmp_path, floating.replace('gravity="0 0 -9.81"', 'gravity="0 0 0"'), "floating.xml")
    )
    result.set_contacts(False)
    result.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    return result


def test_a_spatial_tendon_over_a_free_joint_pulls_its_root(tmp_path):
    """A finger on a floating palm, its tendons anchored on the world: their force on the palm's free joint is a
    wrench on the palm's root link (and the momentum term hears of it). Mutation: the wrench left out."""
    result = floating_finger(tmp_path)
    assert result.controller.term("tendons").spatial.push is not None
    errors = replay(result, result.model, no_ctrl, 0.5)
    assert errors.max() < FLOATING_TOLERANCE, errors.max()
    other = floating_finger(tmp_path)
    other.controller.edit("tendons").spatial.push.roots.clear()
    assert replay(other, other.model, no_ctrl, 0.5).max() > 100 * FLOATING_TOLERANCE


def test_a_spatial_tendon_over_a_ball_joint_is_reported_unsupported(tmp_path):
    """A spatial tendon whose path crosses a ball joint would need a ball joint torque, which the loader does not
    carry for tendons: it says so."""
    ball = FINGER.format(integrator="Euler", damping=0.0).replace(
        '<joint name="mcp" axis="0 1 0" range="-0.2 1.6" damping="0.002"/>', '<joint name="mcp" type="ball"/>'
    )
    result = MJCFLoader().load(mjcf_file(tmp_path, ball.replace('<key qpos="0.5 0.9" qvel="2 -3"/>', ""), "ball.xml"))
    assert any("extensor" in str(note) and "ball joint" in str(note) for note in result.unsupported)


def test_the_tendon_jacobian_is_mujocos_dense_row(tmp_path):
    """The term's Jacobian, rebuilt from MuJoCo's sparse ten_J, equals MuJoCo's length derivative by finite
    differences (a wrong column map would move a tendon's force to another joint)."""
    result, model = load(tmp_path, "Euler")
    spatial = result.controller.term("tendons").spatial.paths
    data = mujoco.MjData(model)
    data.qpos[:] = [0.3, 1.1]
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_tendon(model, data)
    jacobian = spatial.dense(data)
    for i in range(model.nv):
        shifted = mujoco.MjData(model)
        shifted.qpos[:] = data.qpos
        shifted.qpos[i] += 1e-7
        mujoco.mj_kinematics(model, shifted)
        mujoco.mj_comPos(model, shifted)
        mujoco.mj_tendon(model, shifted)
        derivative = (shifted.ten_length - data.ten_length)[spatial.tendons] / 1e-7
        column = list(spatial.dofs).index(i)
        np.testing.assert_allclose(jacobian[:, column], derivative, atol=1e-5)


SERVO = FINGER.replace(
    "</tendon>",
    """</tendon>
  <actuator><position name="pull" tendon="extensor" kp="300" kv="{kv}" ctrlrange="0.07 0.11" forcerange="-4 4"/>
  </actuator>""",
)


def servo_ctrl(step, data):
    return np.array([0.09 + 0.02 * np.sin(step * 0.01)])


@pytest.mark.parametrize(
    "integrator, kv, tolerance",
    [("Euler", 2.0, SPATIAL_TOLERANCE), ("implicitfast", IMPLICIT_DAMPING, IMPLICIT_TOLERANCE)],
)
@pytest.mark.usefixtures("terms")
def test_a_spatial_tendon_servo_matches_mujoco(tmp_path, monkeypatch, integrator, kv, tolerance):
    """A position servo (with kv and a forcerange) on the extensor's length: MuJoCo's law along the path at every
    step, kv explicit under Euler; under implicitfast the drives hold kv's diagonal (noted). Measured 4.7e-7 (Euler)
    and 1.4e-4 rad (implicitfast); the mutation, the servo left out, 1.2."""
    from loader.runtime.actuators import SpatialActuators

    path = mjcf_file(tmp_path, SERVO.format(integrator=integrator, damping=0.0, kv=kv), "servo.xml")
    result = MJCFLoader().load(path)
    assert [a.mapped for a in result.actuators] == [True]
    assert any("J^T J" in str(note) for note in result.approximations) == (integrator != "Euler")
    errors = replay(result, result.model, servo_ctrl, 1.0)
    assert errors.max() < tolerance, errors.max()
    monkeypatch.setattr(SpatialActuators, "contribute", lambda self, step: None)
    other = MJCFLoader().load(path)
    assert replay(other, other.model, servo_ctrl, 1.0).max() > 10 * tolerance
