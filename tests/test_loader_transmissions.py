"""Actuators on site, slider-crank and free-joint transmissions: MuJoCo's own length and moment at SAPIEN's state
every step, the force moment^T f as joint forces and root wrenches (loader/runtime/transmissions.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import replay

from loader import MJCFLoader
from loader.runtime.transmissions import MomentPaths

ARM = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><site name="ref" pos="0.1 0 -0.4"/>
    <body name="upper"><joint name="shoulder" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" size="0.03" fromto="0 0 0 0 0 -0.3"/>
      <body name="lower" pos="0 0 -0.3"><joint name="elbow" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" size="0.03" fromto="0 0 0 0 0 -0.3"/><site name="tip" pos="0 0 -0.3"/></body></body>
  </worldbody>
  <actuator>{actuator}</actuator>
  <keyframe><key qpos="0.3 -0.4"/></keyframe>
</mujoco>"""
SITE_MOTOR = '<motor site="tip" gear="1 0 0.5 0 0.2 0" ctrlrange="-2 2"/>'
SITE_SERVO = '<position site="tip" refsite="ref" gear="0 0 1 0 0 0" kp="20" ctrlrange="-0.5 0.5"/>'
SLIDER = """<mujoco><option timestep="0.002"><flag contact="disable"/></option>
  <worldbody>
    <body name="crank"><joint name="turn" axis="0 1 0" damping="0.01"/>
      <geom type="capsule" size="0.02" fromto="0 0 0 0.1 0 0"/><site name="pin" pos="0.1 0 0"/></body>
    <body name="slider" pos="0.3 0 0"><joint name="slide" type="slide" axis="1 0 0" damping="0.5"/>
      <geom type="box" size="0.03 0.03 0.03"/><site name="end"/></body>
  </worldbody>
  <actuator><general cranksite="pin" slidersite="end" cranklength="0.25" gainprm="2" ctrlrange="-1 1"/></actuator>
</mujoco>"""
FLOATING = """<mujoco><option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body name="ball"><freejoint name="free"/><geom type="box" size="0.05 0.03 0.02" mass="0.3"/>
      <site name="centre" pos="0.02 0 0"/>
      <body name="flap" pos="0.05 0 0"><joint name="hinge" axis="0 0 1"/>
        <geom type="capsule" size="0.01" fromto="0 0 0 0.1 0 0" mass="0.05"/></body></body>
  </worldbody>
  <actuator><motor joint="free" gear="0 0 1 0 0.1 0" ctrlrange="-5 5"/>
    <motor site="centre" gear="0 1 0 0.02 0 0" ctrlrange="-1 1"/><motor joint="hinge" ctrlrange="-0.1 0.1"/></actuator>
</mujoco>"""

# rad or m over 1 s, SAPIEN against MuJoCo under the same ctrl, fixed base; measured on the arm 1.8e-7 (a site
# motor) and 7.1e-6 (a site servo on a reference site), on the slider-crank 4.1e-6 (one-step velocities from random
# states agree to 1.7e-7; mujoco 3.17.0, sapien 3.0.3); with the moments left out 0.088, 3.5 and 2.9
TOLERANCE = 3e-5
# rad or m over 0.5 s on the floating body (the harness's floating rollout tolerance): a tumbling body amplifies
# float32 rounding, measured 1.0e-4 (its one-step velocities agree to 2.6e-6 from random states); the mutation 1.2
FLOATING_TOLERANCE = 5e-4


def _sine(step: int, data) -> np.ndarray:
    t = step * 0.002
    return np.array([np.sin(3 * t + a) for a in range(data.ctrl.size)]) * 0.8


@pytest.mark.parametrize(
    "document",
    [ARM.format(integrator="Euler", actuator=SITE_MOTOR), ARM.format(integrator="Euler", actuator=SITE_SERVO), SLIDER],
    ids=["site", "refsite", "slidercrank"],
)
def test_a_site_or_slider_crank_actuator_follows_mujoco(tmp_path, monkeypatch, document):
    result = MJCFLoader().load(mjcf_file(tmp_path, document, "m.xml"))
    assert all(a.mapped and a.moment for a in result.actuators) and not result.unsupported
    errors = replay(result, result.model, _sine, 1.0)
    assert errors.max() < TOLERANCE, errors.max()
    monkeypatch.setattr(MomentPaths, "dense", lambda self, data: np.zeros((self.tendons.size, self.dofs.size)))
    other = MJCFLoader().load(mjcf_file(tmp_path, document, "m.xml"))
    assert replay(other, other.model, _sine, 1.0).max() > 1000 * TOLERANCE


def test_a_free_joint_and_a_floating_site_actuator_push_the_root_as_mujoco(tmp_path, monkeypatch):
    """A joint actuator on the free joint (a force and a torque) and a site motor on the floating body: their
    share on the free joint is a wrench on the root link."""
    path = mjcf_file(tmp_path, FLOATING, "floating.xml")
    result = MJCFLoader().load(path)
    assert [a.moment for a in result.actuators] == [True, True, False]
    errors = replay(result, result.model, _sine, 0.5)
    assert errors.max() < FLOATING_TOLERANCE, errors.max()
    monkeypatch.setattr(MomentPaths, "dense", lambda self, data: np.zeros((self.tendons.size, self.dofs.size)))
    other = MJCFLoader().load(path)
    assert replay(other, other.model, _sine, 0.5).max() > 10 * FLOATING_TOLERANCE


def test_a_site_actuator_on_a_ball_joint_chain_is_noted_unmapped(tmp_path):
    document = ARM.format(integrator="Euler", actuator=SITE_MOTOR).replace(
        'axis="0 1 0" damping', 'type="ball" damping'
    )
    result = MJCFLoader().load(mjcf_file(tmp_path, document, "ball.xml"))
    assert [(n.kind, n.reason) for n in result.unsupported] == [("actuator", "its transmission moves a ball joint")]


def test_the_moment_is_mujocos_own_where_its_sparse_pattern_drops_an_entry(tmp_path):
    """At qpos0 the tip's vertical force has no moment about either hinge, and MuJoCo leaves the row empty; the
    dense moment is then zero, and at a bent pose it is MuJoCo's Jacobian row."""
    result = MJCFLoader().load(mjcf_file(tmp_path, ARM.format(integrator="Euler", actuator=SITE_SERVO), "m.xml"))
    paths = result.controller.term("actuators").moments
    model = result.model
    lengths, moment = paths.measure(np.zeros(model.nq))
    assert np.array_equal(moment, np.zeros((1, 2)))
    qpos = np.array([0.3, -0.4])
    lengths, moment = paths.measure(qpos)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    jacobian, tip = np.zeros((3, model.nv)), model.site("tip").id
    mujoco.mj_jacSite(model, data, jacobian, None, tip)
    assert np.allclose(moment[0], jacobian[2]) and lengths[0] == pytest.approx(data.site_xpos[tip, 2] + 0.4)
