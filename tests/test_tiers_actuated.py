"""The actuated tiers: the same ctrl on both sides passes on a clean load, and each deliberate actuator mistake
(a kp 5 % off, a wrong gear sign, an inverted coupling ratio, servo gains halved) makes them fail; the scene is
left as the other tiers expect; unmapped actuators skip the tier by name; saturated servos are judged as they are."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from conformance import commands, tolerances
from conformance.corpus import menagerie_root
from conformance.session import open_session
from conformance.tiers import TIERS

TOL = tolerances.load()

# A fixed-base arm hanging under gravity (clear of its limits at the held ctrl), authored with Euler (kv explicit, as
# the loader applies it under Euler): a position servo, a geared motor, and a motor on a fixed tendon coupling two
# hinges with ratio 1 : 2.
ARM = """
<mujoco model="actuated_arm">
  <compiler angle="radian"/>
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1" pos="0 0 -1"/>
    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.05" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
      <body name="lower" pos="0 0 -0.3">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.02" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.25" size="0.025"/>
      </body>
    </body>
    <body name="left" pos="0 0.5 0">
      <joint name="left" type="hinge" axis="0 0 1" damping="0.01"/>
      <geom type="box" size="0.1 0.02 0.02" pos="0.1 0 0" mass="0.5"/>
    </body>
    <body name="right" pos="0 -0.5 0">
      <joint name="right" type="hinge" axis="0 0 1" damping="0.01"/>
      <geom type="box" size="0.1 0.02 0.02" pos="0.1 0 0" mass="0.5"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="pair"><joint joint="left" coef="1"/><joint joint="right" coef="2"/></fixed>
  </tendon>
  <actuator>
    <position name="servo" joint="shoulder" kp="40" kv="2" ctrlrange="-1.5 1.5"/>
    <motor name="torque" joint="elbow" gear="2" ctrlrange="-1 1"/>
    <motor name="coupled" tendon="pair" ctrlrange="-0.2 0.2"/>
  </actuator>
</mujoco>
"""


def _write(tmp_path: Path, text: str, name: str = "arm.xml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _session(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return open_session(str(path))


def _tier(session, tier: str, model: mujoco.MjModel | None = None):
    return TIERS[tier](session.result, session.model if model is None else model, 0, TOL)


def _failed(report) -> set[str]:
    return {m.name for m in report.metrics if not m.passed}


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    return _write(tmp_path_factory.mktemp("arm"), ARM)


def test_clean_arm_passes_with_its_own_euler_integrator_and_actuation_on(arm):
    session = _session(arm)
    report = _tier(session, "actuated")
    assert report.status == "pass", report.to_dict()
    assert report.settings["integrator_authored"] == "mjINT_EULER"
    assert report.settings["integrator_reference"] == "mjINT_EULER"
    assert report.settings["actuators"] is True
    # every actuator received a changing ctrl, and MuJoCo's forces are not all zero
    trace = report.actuators
    assert trace.names == ["servo", "torque", "coupled"]
    assert np.all(np.ptp(trace.ctrl, axis=0) > 0)
    assert np.all(np.abs(trace.mujoco_force).max(axis=0) > 0)


def test_actuator_forces_agree_when_the_states_agree(arm):
    trace = _tier(_session(arm), "actuated").actuators
    # both force series come from states that agree to 1e-6 rad: forces agree to kp * 1e-6 and better
    np.testing.assert_allclose(trace.sapien_force, trace.mujoco_force, atol=1e-4)


def _kp_five_percent(session) -> None:
    changed = 0
    for drive in session.result.controller.edit_laws().values():
        if drive.stiffness > 0:
            drive.stiffness *= 1.05
            changed += 1
    assert changed


def test_a_five_percent_kp_error_is_caught(arm):
    session = _session(arm)
    _kp_five_percent(session)
    report = _tier(session, "actuated")
    assert report.status == "fail"
    assert {"one_step_qvel", "rollout_qpos"} <= _failed(report)


@pytest.mark.parametrize(
    "edit", [('gear="2"', 'gear="-2"'), ('coef="2"', 'coef="0.5"')], ids=["gear sign", "inverted coupling ratio"]
)
def test_a_mistake_in_the_sapien_copy_only_is_caught(tmp_path, arm, edit):
    assert edit[0] in ARM
    mutated = _session(_write(tmp_path, ARM.replace(*edit), "mutated.xml"))
    reference = _session(arm).model  # MuJoCo runs the correct model
    report = _tier(mutated, "actuated", model=reference)
    assert report.status == "fail"
    assert {"one_step_qvel", "rollout_qpos"} <= _failed(report)


def test_the_scene_is_left_as_the_other_tiers_expect(arm):
    session = _session(arm)
    result = session.result
    qpos_before, _ = result.mapping.get_state(result.articulations)
    contact = _tier(session, "actuated_contact")
    assert contact.status == "pass", contact.to_dict()
    assert "actuators" not in result.controller.names  # actuators off again (the dynamics tier commands forces itself)
    groups = [
        list(s.get_collision_groups())
        for art in result.articulations
        for link in art.links
        for s in link.collision_shapes
    ]
    assert any(g[0] or g[1] for g in groups), "actuated_contact keeps contacts on for dynamics"
    _tier(session, "actuated")
    assert "actuators" not in result.controller.names
    qpos_after, _ = result.mapping.get_state(result.articulations)
    np.testing.assert_allclose(qpos_after, qpos_before, atol=1e-6)
    for art in result.articulations:
        np.testing.assert_array_equal(np.asarray(art.get_qf()), 0.0)
    assert _tier(session, "actuated_contact").status == "skipped", "contacts are off after actuated"


def test_unmapped_actuators_skip_the_tier_by_name(tmp_path):
    text = ARM.replace(
        '<motor name="torque" joint="elbow" gear="2" ctrlrange="-1 1"/>',
        '<general name="custom" joint="elbow" dyntype="user" ctrlrange="0 1"/>',  # user dynamics: unmapped
    )
    session = _session(_write(tmp_path, text))
    for tier in ("actuated", "actuated_contact"):
        report = _tier(session, tier)
        assert report.status == "skipped"
        assert "custom" in report.notes[0] and "servo" not in report.notes[0]


def test_a_saturating_servo_is_judged_unscaled_and_passes(tmp_path):
    # a stiff servo with a tight forcerange: a 5 % step of its 3 rad ctrlrange needs 600 N m, the limit is 5;
    # the loader clamps as MuJoCo does, so the tier needs no scaling and still passes (implicitfast: under Euler
    # an explicit kv of 60 on this arm makes MuJoCo itself amplify a 1e-6 perturbation 1.4e4 times)
    text = ARM.replace('kp="40" kv="2"', 'kp="4000" kv="60" forcerange="-5 5"').replace(
        'integrator="Euler"', 'integrator="implicitfast"'
    )
    session = _session(_write(tmp_path, text))
    report = _tier(session, "actuated")
    assert report.settings["ctrl_scale"] == 1.0
    assert report.settings["saturated_steps"] > 10
    forcerange = session.model.actuator_forcerange[0]
    assert np.isclose(np.abs(report.actuators.mujoco_force[:, 0]).max(), forcerange[1])
    assert report.status == "pass", report.to_dict()


def test_ctrl_sequence_holds_steps_and_stays_inside_ctrlrange(arm):
    model = mujoco.MjModel.from_xml_path(str(arm))
    hold = commands.hold_ctrl(model, model.qpos0, np.zeros(model.nv))
    ctrl = commands.ctrl_sequence(model, hold, 500, 3, 0.5, 0.5, (0.2, 0.5))
    np.testing.assert_array_equal(ctrl[:100], np.tile(hold, (100, 1)))
    assert np.all(ctrl[100] == ctrl[249]) and np.any(ctrl[100] != hold)
    assert np.ptp(ctrl[250:], axis=0).min() > 0
    low, high = model.actuator_ctrlrange.T
    assert np.all(ctrl >= low) and np.all(ctrl <= high)
    # the held ctrl makes the servo hold its start: its force at qpos0 is zero
    data = mujoco.MjData(model)
    data.ctrl[:] = hold
    mujoco.mj_forward(model, data)
    assert data.actuator_force[0] == pytest.approx(0.0, abs=1e-12)


def _spot() -> Path:
    root, _ = menagerie_root()
    if root is None or not (root / "boston_dynamics_spot/spot.xml").is_file():
        pytest.skip("Menagerie slice not installed")
    return root / "boston_dynamics_spot/spot.xml"


def _flip_gears(session) -> None:
    actuators = session.result.controller.edit("actuators").actuators  # the list result.actuators shows
    for i, actuator in enumerate(actuators):
        actuators[i] = dataclasses.replace(actuator, gear=-actuator.gear)


def _halve_servo_gains(session) -> None:
    for drive in session.result.controller.edit_laws().values():
        drive.stiffness *= 0.5


@pytest.mark.parametrize(
    "mutation,tier,metric",
    [
        (None, "actuated", None),
        (None, "actuated_contact", None),
        (_kp_five_percent, "actuated", "one_step_qvel"),
        (_flip_gears, "actuated", "rollout_qpos"),
        (_flip_gears, "actuated_contact", "final_pose_band"),
        (_halve_servo_gains, "actuated_contact", "rest_height"),
    ],
    ids=["clean", "clean-contact", "kp-5%", "gear-sign", "gear-sign-contact", "half-gains-contact"],
)
def test_spot_standing_on_its_servos(mutation, tier, metric):
    session = _session(_spot())
    if mutation is not None:
        mutation(session)
    report = _tier(session, tier)
    if mutation is None:
        assert report.status == "pass", report.to_dict()
    else:
        assert report.status == "fail" and metric in _failed(report), report.to_dict()


def test_the_manifest_can_take_unmapped_actuators_out_of_both_sides(tmp_path):
    text = ARM.replace(
        '<motor name="torque" joint="elbow" gear="2" ctrlrange="-1 1"/>',
        '<general name="custom" joint="elbow" dyntype="user" ctrlrange="0 1"/>',  # user dynamics: unmapped
    )
    session = _session(_write(tmp_path, text))
    removed = TOL.with_overrides(settings={"actuated": {"unmapped": "remove"}})
    report = TIERS["actuated"](session.result, session.model, 0, removed)
    assert report.status == "pass", report.to_dict()
    assert report.settings["actuators_removed"] == ["custom"] and "custom" in report.notes[0]
    assert np.all(report.actuators.mujoco_force[:, 1] == 0) and np.all(report.actuators.sapien_force[:, 1] == 0)
    assert TIERS["actuated"](session.result, session.model, 0, TOL).status == "skipped"  # the default


def test_an_inverted_equality_coupling_stands_far_above_the_soft_equality_gap(tmp_path):
    """The loader's equality fixture (follower = 2 x driver) fails the tier even when correct: MuJoCo's equality
    is soft, PhysX's tendon spring is not the same law (one-step qvel 1.3e-3, rollout 7.9e-5, as the panda's finger
    in the manifest). Inverting the ratio in SAPIEN's copy must still stand out by two orders of magnitude."""
    fixture = Path(__file__).resolve().parent / "fixtures" / "coupled_joints.xml"
    text = fixture.read_text()
    edit = ('polycoef="0 2 0 0 0"', 'polycoef="0 0.5 0 0 0"')
    assert edit[0] in text
    clean = _tier(_session(fixture), "actuated")
    mutated = _tier(
        _session(_write(tmp_path, text.replace(*edit), "inverted.xml")), "actuated", model=_session(fixture).model
    )
    for name in ("one_step_qvel", "rollout_qpos"):
        before = next(m.max for m in clean.metrics if m.name == name)
        after = next(m.max for m in mutated.metrics if m.name == name)
        assert after > 50 * before, (name, before, after)


UNSTABLE = """<mujoco><option integrator="{integrator}"/>
  <worldbody><body><joint name="j"/><geom size="0.02"/></body></worldbody>
  <actuator><velocity joint="j" kv="1"/></actuator>
</mujoco>"""


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_a_reference_that_blows_up_is_skipped_not_judged(tmp_path, integrator):
    """kv = 1 on a 2 cm sphere (dt kv / I about 400): explicit under Euler, MuJoCo itself blows up (bad qacc) and
    resets its state, so there is no reference; implicit under implicitfast it is stable and the tier judges."""
    session = _session(_write(tmp_path, UNSTABLE.format(integrator=integrator)))
    report = _tier(session, "actuated")
    if integrator == "Euler":
        assert report.status == "skipped" and "unstable under EULER" in report.notes[0], report.to_dict()
    else:
        assert report.status == "pass", report.to_dict()


@pytest.mark.parametrize("pair", [False, True])
def test_a_model_whose_geoms_cannot_touch_skips_the_contact_run_saying_so(tmp_path, pair):
    """Every geom's contype and conaffinity 0 (a gymnasium swimmer's defaults): `actuated_contact` has nothing to
    judge and says why, rather than blaming an earlier tier for SAPIEN's contacts. One explicit <pair> (floor and
    upper arm) is a contact MuJoCo may make: then the tier is not skipped for that reason."""
    text = ARM.replace("<worldbody>", '<default><geom contype="0" conaffinity="0"/></default><worldbody>', 1)
    if pair:
        text = text.replace(
            '<geom type="capsule" fromto="0 0 0 0 0 -0.3"', '<geom name="arm" type="capsule" fromto="0 0 0 0 0 -0.3"'
        )
        text = text.replace("</tendon>", '</tendon><contact><pair geom1="floor" geom2="arm"/></contact>')
    report = _tier(_session(_write(tmp_path, text)), "actuated_contact")
    cannot = report.status == "skipped" and "no geom can make a contact" in report.notes[0]
    assert cannot == (not pair), (report.status, report.notes[:1])
