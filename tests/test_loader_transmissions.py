"""Actuators on site, slider-crank and free-joint transmissions: MuJoCo's own length and moment at SAPIEN's state
every step, the force moment^T f as joint forces and root wrenches (loader/runtime/transmissions.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import contact_free, replay

from loader import MJCFLoader
from loader.runtime.tendons import TendonPaths
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
@pytest.mark.usefixtures("terms")
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


MUSCLES = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><site name="origin" pos="0 0.02 0.05"/>
    <body name="upper"><joint name="shoulder" axis="0 1 0" range="-1.5 1.5" damping="0.05"/>
      <geom type="capsule" size="0.02" fromto="0 0 0 0.3 0 0" mass="0.5"/><site name="mid" pos="0.15 0 0.02"/>
      <body name="lower" pos="0.3 0 0"><joint name="elbow" axis="0 1 0" range="-2 2" damping="0.05"/>
        <geom type="capsule" size="0.02" fromto="0 0 0 0.25 0 0" mass="0.3"/><site name="insert" pos="0.1 0 0.02"/>
      </body></body>
  </worldbody>
  <tendon><spatial name="flexor"><site site="origin"/><site site="mid"/><site site="insert"/></spatial>
    <spatial name="short"><site site="mid"/><site site="insert"/></spatial></tendon>
  <actuator><muscle tendon="flexor" force="40"/><muscle tendon="short" force="20"/>
    <muscle joint="shoulder" force="5" lengthrange="-1.5 1.5"/></actuator>
  <keyframe><key qpos="0.2 0.4"/></keyframe>
</mujoco>"""
# rad over 1 s under a ctrl sine: Euler measured 1.9e-7 (mujoco 3.17.0, sapien 3.0.3); under implicitfast 3.2e-4,
# the coupled part of the two-joint muscle's rate derivative explicit (noted), 1.8e-3 with none of it implicit
MUSCLE_TOLERANCE = 1e-5
IMPLICIT_MUSCLE_TOLERANCE = 1e-3
# rad/s, one step from random states and activations: 2.3e-6 (Euler) and 2.1e-6 (implicitfast); 0.15 under
# implicitfast without the implicit derivative
ONE_STEP_TOLERANCE = 2e-5


def _muscle_sine(step: int, data) -> np.ndarray:
    return 0.5 + 0.5 * np.sin(np.array([3.0, 5.0, 2.0]) * step * 0.002)


def _one_step_with_activations(result) -> float:
    from support.lockstep import one_step

    rng, model, worst = np.random.default_rng(0), result.model, 0.0
    for _ in range(10):
        qpos, qvel, ctrl, act = (
            rng.uniform(-0.5, 0.5, 2),
            rng.normal(size=2),
            rng.uniform(0, 1, 3),
            rng.uniform(0, 1, 3),
        )
        data = mujoco.MjData(model)
        data.act[:] = result.controller.activation.act[:] = act
        worst = max(worst, float(one_step(result, model, qpos, qvel, ctrl, data=data, advance=False).max()))
    return worst


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_muscles_follow_mujoco(tmp_path, monkeypatch, integrator):
    """MuJoCo's muscles on spatial tendons and on a joint: their activation dynamics and force-length-velocity
    curves are MuJoCo's own functions at SAPIEN's state, and under implicitfast their rate derivative joins the
    drives. Mutations: the muscles' force left out; under implicitfast, their rate derivative left explicit."""
    from loader.runtime.transmissions import MuscleActuators, MuscleLaws

    path = mjcf_file(tmp_path, MUSCLES.format(integrator=integrator), "muscles.xml")
    result = MJCFLoader().load(path)
    assert all(a.mapped and a.muscle for a in result.actuators) and not result.unsupported
    coupled = [n.name for n in result.approximations if n.kind == "actuator"]
    assert coupled == ([] if integrator == "Euler" else ["actuator0", "actuator1"])  # tendons over both joints
    tolerance = MUSCLE_TOLERANCE if integrator == "Euler" else IMPLICIT_MUSCLE_TOLERANCE
    assert replay(result, result.model, _muscle_sine, 1.0).max() < tolerance
    assert _one_step_with_activations(MJCFLoader().load(path)) < ONE_STEP_TOLERANCE
    if integrator == "implicitfast":
        with monkeypatch.context() as patch:
            patch.setattr(MuscleLaws, "damping", lambda self, inputs, length, rate: np.zeros(len(self.indices)))
            assert _one_step_with_activations(MJCFLoader().load(path)) > 100 * ONE_STEP_TOLERANCE
    monkeypatch.setattr(MuscleActuators, "contribute", lambda self, step: None)
    other = MJCFLoader().load(path)
    assert replay(other, other.model, _muscle_sine, 1.0).max() > 100 * tolerance


# Adhesion: a pad at the end of a sprung arm (a hinge, then a slide towards the surface) 1.3 to 1.5 cm above a
# floor plane or a free box, no gravity. The pad's box finds its contacts in its gap band (detected, no constraint
# rows and no contact force: MuJoCo's moment from the two bodies' Jacobians) or within its margin (active contacts:
# the moment from their constraint rows); SAPIEN makes no contact force before the geoms touch.
ADHESION = """<mujoco><option timestep="0.002" gravity="0 0 0" integrator="implicitfast" cone="{cone}"/>
  <worldbody>
    <body name="arm" pos="-0.2 0 {height}"><joint name="swing" axis="0 1 0" stiffness="20" damping="0.5"/>
      <geom type="capsule" size="0.01" fromto="0 0 0 0.2 0 0" contype="0" conaffinity="0" mass="0.1"/>
      <body name="pad" pos="0.2 0 0"><joint name="reach" type="slide" axis="0 0 1" stiffness="100" damping="2"/>
        <geom name="pad" type="box" size="0.03 0.02 0.01" {band} mass="0.05"/></body></body>{surface}
  </worldbody>
  <actuator><adhesion name="stick" body="pad" ctrlrange="0 1" gain="1"/></actuator>
  <keyframe><key qpos="0.03 0{box}"/></keyframe>
</mujoco>"""
FLOOR = '<geom name="floor" type="plane" size="1 1 0.1"/>'
FREE_BOX = '<body name="box" pos="0 0 -0.03"><freejoint/><geom type="box" size="0.05 0.05 0.03" mass="20"/></body>'
IN_GAP, IN_MARGIN = 'margin="0" gap="0.02"', 'margin="0.02"'


def _adhesion(band: str = IN_GAP, surface: str = FLOOR, cone: str = "pyramidal", height: float = 0.03) -> str:
    box = " 0 0 -0.03 1 0 0 0" if surface == FREE_BOX else ""  # the free box where it is built
    return ADHESION.format(band=band, surface=surface, cone=cone, height=height, box=box)


# name: the document both sides run. Within the margin MuJoCo's own contact pushes the pad away, and so does
# SAPIEN's, the model's own contacts being MuJoCo's (docs/mapping.md#contacts-as-rows)
ADHESIONS = {
    "gap-floor": _adhesion(),
    "gap-free-box": _adhesion(surface=FREE_BOX),
    "margin-floor-pyramidal": _adhesion(IN_MARGIN),
    "margin-floor-elliptic": _adhesion(IN_MARGIN, cone="elliptic"),
}
# m over 0.5 s of a pull of 0 to 1 N: measured 6.6e-9 on the floor, 4.4e-8 with the free box, 2e-9 in the margins
# (mujoco 3.17.0, sapien 3.0.3); the moment's sign flipped
# 1.3e-2, MuJoCo's collision skipped 1.2e-2, and without contacts (out of reach, or switched off) 2.6e-9
ADHESION_TOLERANCE = 1e-6


def _pull(step: int, data) -> np.ndarray:
    return np.array([0.5 + 0.5 * np.sin(20 * step * 0.002)])


def _adhesion_error(tmp_path, name: str) -> float:
    result = MJCFLoader().load(mjcf_file(tmp_path, ADHESIONS[name], "adhesion.xml"))
    return float(replay(result, result.model, _pull, 0.5).max())


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("name", list(ADHESIONS))
def test_an_adhesion_actuator_pulls_along_its_contacts_as_mujoco(tmp_path, monkeypatch, name):
    """MuJoCo's body transmission at SAPIEN's pose: its collision and constraint rows, then its moment (the mean
    normal Jacobian of the pad's contacts, on the floor or on a free box, whose share is a root wrench). Mutations:
    the moment's sign flipped; MuJoCo's collision skipped (no contacts, no moment)."""
    result = MJCFLoader().load(mjcf_file(tmp_path, ADHESIONS[name], "adhesion.xml"))
    assert all(a.mapped and a.moment for a in result.actuators) and not result.unsupported
    assert _adhesion_error(tmp_path, name) < ADHESION_TOLERANCE
    dense = MomentPaths.dense
    with monkeypatch.context() as patch:
        patch.setattr(MomentPaths, "dense", lambda self, data: -dense(self, data))
        assert _adhesion_error(tmp_path, name) > 1000 * ADHESION_TOLERANCE
    monkeypatch.setattr(MomentPaths, "pose", TendonPaths.pose)
    assert _adhesion_error(tmp_path, name) > 1000 * ADHESION_TOLERANCE


@pytest.mark.usefixtures("terms")
def test_an_adhesion_actuator_without_contacts_does_nothing(tmp_path, monkeypatch):
    """Without contacts MuJoCo's adhesion has no moment: the pad raised out of reach of the floor, or SAPIEN's
    contacts switched off (and MuJoCo's with them) with the pad in the gap band. Mutation: the switch not passed
    on to the moment's collision."""
    path = mjcf_file(tmp_path, _adhesion(height=0.2), "far.xml")
    result = MJCFLoader().load(path)
    forces = []
    errors = replay(
        result, result.model, lambda step, data: forces.append(data.qfrc_actuator.copy()) or _pull(step, data), 0.5
    )
    assert errors.max() < ADHESION_TOLERANCE and not np.any(forces)
    path = mjcf_file(tmp_path, _adhesion(), "gap.xml")
    result, model = contact_free(path)
    assert replay(result, model, _pull, 0.5).max() < ADHESION_TOLERANCE
    monkeypatch.setattr(MomentPaths, "contacts", lambda self, enabled: None)
    result, model = contact_free(path)
    assert replay(result, model, _pull, 0.5).max() > 1000 * ADHESION_TOLERANCE


def _poses(model: mujoco.MjModel, count: int, spread: np.ndarray, seed: int = 0):
    """`count` poses about the first keyframe (or qpos0): each position coordinate moved by up to `spread`."""
    rng, data = np.random.default_rng(seed), mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(count):
        yield data.qpos + rng.uniform(-1, 1, model.nq) * spread


def _fly_on_a_floor():
    from support.corpus import _package_dir

    package = _package_dir("dm_control")
    path = package / "locomotion/walkers/assets/fruitfly_v2/fruitfly.xml" if package else None
    if path is None or not path.is_file():
        pytest.skip("dm_control's fruit fly is not installed")
    spec = mujoco.MjSpec.from_file(str(path))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    return spec


@pytest.mark.parametrize(
    "name", ["gap-floor", "gap-free-box", "margin-floor-pyramidal", "margin-floor-elliptic", "fly"]
)
def test_a_body_moment_is_mujocos_forward_pass_at_every_pose(tmp_path, name):
    """The passes the moment runs (kinematics, collision, constraint rows, transmission) give `mj_forward`'s
    moment bit for bit, at poses with contacts in the gap band, within the margin and none; and the DoFs the plan
    takes for a body transmission hold every entry MuJoCo's moment has (the fruit fly on a floor: its legs' claws
    and its labrum against the floor and its own body, elliptic cones)."""
    source = _fly_on_a_floor() if name == "fly" else mjcf_file(tmp_path, ADHESIONS[name], "adhesion.xml")
    result = MJCFLoader().load(source)
    model, paths = result.model, result.controller.term("actuators").moments
    body = np.flatnonzero(model.actuator_trntype == int(mujoco.mjtTrn.mjTRN_BODY))
    assert body.size and all(result.actuators[a].mapped for a in body)
    if name == "fly":  # the root up to 3 mm up or down (the fly is in cm), the joints moved up to 0.3 rad
        spread = np.r_[0, 0, 0.3, np.zeros(4), np.full(model.nq - 7, 0.3)]
    else:
        spread = np.r_[0.2, 0.01, np.full(model.nq - 2, 0.01)]
    data, kinds = mujoco.MjData(model), set()
    for qpos in _poses(model, 20, spread):
        lengths, moment = paths.measure(qpos)
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        full = np.zeros((model.nu, model.nv))
        mujoco.mju_sparse2dense(full, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind)
        rows = [paths.index(a) for a in body]
        assert np.array_equal(moment[rows], full[body][:, paths.dofs]), qpos
        assert not np.delete(full[body], paths.dofs, axis=1).any()  # nothing outside the plan's DoFs
        assert not lengths[rows].any()
        pads = np.isin(model.geom_bodyid[data.contact.geom[: data.ncon]], model.actuator_trnid[body, 0]).any(axis=1)
        kinds.update(data.contact.exclude[: data.ncon][pads].tolist() or ["none"])
    expected = {"fly": {0, 1}, "gap": {0, 1, "none"}, "margin": {0, "none"}}[name.split("-")[0]]
    assert kinds >= expected, kinds  # 0: a contact within the margin, 1: one in the gap band
