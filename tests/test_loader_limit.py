"""MuJoCo's soft joint limits on the joint drives (loader/runtime/limits.py); MuJoCo is the oracle.

A pendulum swings through +-30 degrees of range and bounces on both soft ends for 1.2 s. Measured (mujoco 3.17.0,
sapien 3.0.3): 4.4e-7 rad without damping, 2.6e-7 with damping 0.05 (its implicit part as armature, the row
scaled), 2.2e-5 held by a position servo; PhysX's hard limits instead: 4.4e-2, 3.5e-2, 6.9e-2.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.lockstep import one_step, paired_rollout

from loader import MJCFLoader
from loader.runtime.limits import LimitRow

TOLERANCE = 1e-4  # rad over 1.2 s, measured 2.2e-5 at most
PENDULUM = """<mujoco><option timestep="0.002"/><worldbody><body name="arm" pos="0 0 1">
  <joint name="hinge" axis="0 1 0" range="-30 30" damping="{damping}"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".3"/></body></worldbody>{actuator}</mujoco>"""
CASES = {
    "free": ("0", ""),
    "damped": ("0.05", ""),
    "servo": ("0", '<actuator><position joint="hinge" kp="2" kv="0.1"/></actuator>'),
}


def _bounce(name: str, hard: bool = False) -> float:
    damping, actuator = CASES[name]
    xml = PENDULUM.format(damping=damping, actuator=actuator)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    if hard:  # the mapping before: PhysX's hard limit at MuJoCo's range
        result.controller.without("limits")
    worst = float(paired_rollout(result, model, data, 600, lambda step, data: np.full(
        model.nu, np.sin(0.02 * step)) if model.nu else None).qpos.max())
    assert data.qpos.min() < -0.5 or data.qpos.max() > 0.5 or name == "servo"  # it reached a soft end
    return worst


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_pendulum_bounces_on_its_soft_limits_as_in_mujoco(name):
    assert _bounce(name) < TOLERANCE


@pytest.mark.parametrize("name", sorted(CASES))
def test_physxs_hard_limits_miss_it(name):
    """The mutation: what the loader did before (measured 3.5e-2 to 6.9e-2)."""
    assert _bounce(name, hard=True) > 100 * TOLERANCE


def _leaving_the_limit() -> float:
    """First step from just past the lower end, moving away from it at 3 rad/s: MuJoCo's row force would pull
    (its reference acceleration is negative) and is clamped to zero."""
    xml = PENDULUM.format(damping="0", actuator="")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    data.qpos[0], data.qvel[0] = model.jnt_range[0][0] - 0.002, 3.0
    mujoco.mj_forward(model, data)
    assert data.nefc == 1 and data.efc_force[0] == 0.0  # the row exists and does not push
    return float(one_step(result, model, data.qpos, data.qvel, data=data).max())


def test_a_limit_row_only_pushes(monkeypatch):
    """Measured 1.1e-4 rad/s (float32 around the one-sided offset); two-sided 0.67."""
    assert _leaving_the_limit() < 1e-3

    def two_sided(self, q, v, timestep, scale):  # the mutation: no offset, the drive pulls as well
        step = original(self, q, v, timestep, scale)
        if step is None:
            return None
        drive, constant, offset = step
        return drive, constant + offset, 0.0
    original = LimitRow.drive
    monkeypatch.setattr(LimitRow, "drive", two_sided)
    assert _leaving_the_limit() > 1e-1


def test_release_puts_physxs_hard_limit_back_and_set_ctrl_widens_it_again():
    xml = PENDULUM.format(damping="0", actuator="")
    result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    joint = result.articulations[0].active_joints[0]
    low, high = np.deg2rad([-30.0, 30.0])
    assert joint.limit[0][0] < low - 0.05 and joint.limit[0][1] > high + 0.05  # out of the rows' way
    result.release()
    np.testing.assert_allclose(joint.limit[0], [low, high], rtol=1e-6)
    result.set_ctrl(None)
    assert joint.limit[0][0] < low - 0.05


def test_frictional_and_coupled_joints_keep_the_hard_limit_and_say_so():
    xml = """<mujoco><worldbody><body><joint name="rough" axis="0 1 0" range="-30 30" frictionloss=".1"/>
      <geom size=".1" pos=".2 0 0"/><body pos=".4 0 0"><joint name="a" axis="0 1 0" range="-30 30"/>
      <geom size=".1" pos=".2 0 0"/><body pos=".4 0 0"><joint name="b" axis="0 1 0" range="-30 30"/>
      <geom size=".1" pos=".2 0 0"/></body></body></body></worldbody>
      <equality><joint joint1="a" joint2="b"/></equality></mujoco>"""
    result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    assert result.controller.term("limits") is None
    kept = {e.name for e in result.approximations if "limit kept as PhysX's hard limit" in e.reason}
    assert kept == {"rough", "a", "b"}


def _humanoid_collapse_speed() -> tuple[float, float]:
    """dm_control's humanoid collapsing onto its floor for 1 s under zero ctrl, through set_ctrl, from the
    harness's start (qpos0, limited joints 5 % inside their ranges): the fastest SAPIEN joint and the fastest
    MuJoCo joint (rad/s or m/s)."""
    from support.corpus import suite_path

    from conformance.reference import initial_state

    model = mujoco.MjModel.from_xml_path(str(suite_path("humanoid")))
    data = mujoco.MjData(model)
    result = MJCFLoader(ignore_classes=[]).load(str(suite_path("humanoid")))
    result.disable_actuators()
    data.qpos[:], data.qvel[:], _ = initial_state(model)
    result.mapping.set_state(result.articulations, data.qpos.copy(), data.qvel.copy())
    run = paired_rollout(result, model, data, round(1.0 / model.opt.timestep))
    return float(run.sapien_speed.max()), float(run.mujoco_speed.max())


COLLAPSE_SPEED_RATIO = 3.0  # measured 2.2 (33.5 against 15.2 rad/s; mujoco 3.17.0, sapien 3.0.3); blown up: 150+


def test_limit_rows_under_contact_stay_finite():
    """Many limit rows with the floor's contacts in one PhysX solve: the one-sided rows' explicit offsets stay
    small enough for PhysX to cancel them (`limit.force_limit`)."""
    sapien_speed, mujoco_speed = _humanoid_collapse_speed()
    assert sapien_speed < COLLAPSE_SPEED_RATIO * mujoco_speed, (sapien_speed, mujoco_speed)


def test_limit_rows_sized_on_speed_blow_up_under_contact(monkeypatch):
    """The deliberate mistake: the force limit sized on |target| + |v| and 1e3 rad/s^2 (the sizing before)."""
    import loader.runtime.limits

    monkeypatch.setattr(loader.runtime.limits, "force_limit", lambda damping, target, v, timestep: max(
        1.0, damping * (abs(target) + abs(v) + timestep * 1e3)))
    sapien_speed, mujoco_speed = _humanoid_collapse_speed()
    assert not sapien_speed < COLLAPSE_SPEED_RATIO * mujoco_speed, (sapien_speed, mujoco_speed)
