"""connect and weld equalities as MuJoCo's soft law on a PhysX D6 joint's drives (loader/soft_row.py,
loader/runtime/equalities.py).

MuJoCo is the oracle. The fixture closes a five-bar loop between two moving links of one articulation, without
joint damping or contacts, where the soft law is exact. Measured (mujoco 3.17.0, sapien 3.0.3): first step from a
closed loop at joint speeds up to 3 rad/s 2.7e-7 rad/s; from a loop open by |r| = 3.6e-5 m (about what gravity
holds it open by) 7.2e-8 at rest (9.5e-6 with the D6 anchored at the child's anchor instead of the midpoint), 2.2e-5
at 1 rad/s (PhysX applies both ends' forces at one point: first order in r times the speed); 0.5 s falling from
qpos0 7.9e-7 rad (1.2e-5 when the rows read the links' velocities as PhysX leaves them after a step, ahead of the
joints' by the velocity-product drift: loader/runtime/state.py). The rigid D6 it replaces: 2e-2 on the first step.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from support.corpus import menagerie_root
from support.lockstep import one_step, paired_rollout

from loader import MJCFLoader
from loader.model.soft_row import SoftRow, diag_approx
from loader.plan.solver_iterations import drive_radii
from loader.runtime.equalities import SoftConnect, SoftWeld


@pytest.fixture(autouse=True)
def d6_form(monkeypatch):
    """These tests measure the D6 form of connects and welds, which the loader uses where a loop moves a ball
    joint. Their fixtures have none, where the loader makes MuJoCo's own rows instead
    (tests/test_loader_couplings.py), so the D6 form is chosen here for every connect and weld."""
    import loader.plan.equalities

    monkeypatch.setattr(loader.plan.equalities, "_joint_row", lambda *args: False)


FIXTURE = Path(__file__).resolve().parents[1] / "corpus" / "fixtures" / "closed_chain.xml"
ONE_STEP = 2e-5  # rad/s, measured 2.3e-6 (closed) and 9.5e-6 (open by 3.6e-5 m, at rest)
ROLLOUT = 4e-6  # rad over 0.5 s, measured 7.9e-7 (1.2e-5 on the links' drifted velocities)

SOLREF_SOLIMP = """<mujoco><option timestep="{dt}"/><worldbody><body pos="0 0 1"><joint axis="0 1 0"/>
<geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".3"/><body name="b" pos=".3 0 0"><joint axis="0 1 0"/>
<geom type="capsule" fromto="0 0 0 0 0 -.3" size=".02" mass=".2"/></body></body></worldbody>
<equality><connect body1="b" body2="world" anchor="0 0 -.3" solref="{solref}" solimp="{solimp}"/></equality>
</mujoco>"""


@pytest.mark.parametrize(
    "solref, solimp, dt",
    [
        ("0.02 1", "0.9 0.95 0.001 0.5 2", 0.002),  # MuJoCo's defaults
        ("0.001 1", "0.5 0.99 0.01 0.3 3", 0.002),  # refsafe clamps the time constant to 2 dt
        ("-1000 -10", "0.8 0.9 0.05 0.7 1", 0.001),  # the direct (stiffness, damping) form, linear sigmoid
        ("0.05 0.3", "0.9 0.9 0.001 0.5 2", 0.002),  # flat impedance
        ("0.02 1", "0.2 0.8 0 0.5 2", 0.002),  # zero width
    ],
)
def test_soft_row_reproduces_mujocos_stiffness_damping_impedance_and_regularizer(solref, solimp, dt):
    model = mujoco.MjModel.from_xml_string(SOLREF_SOLIMP.format(solref=solref, solimp=solimp, dt=dt))
    data = mujoco.MjData(model)
    row = SoftRow.of(model, model.eq_solref[0], model.eq_solimp[0])
    rng = np.random.default_rng(0)
    for shift in np.concatenate([[0.0], rng.uniform(-0.2, 0.2, 5), rng.uniform(-0.003, 0.003, 5)]):
        data.qpos[:] = model.qpos0
        data.qpos[0] += shift
        mujoco.mj_forward(model, data)
        stiffness, damping, imp, _ = data.efc_KBIP[0]
        ours = row.impedance(float(np.linalg.norm(data.efc_pos[:3])))
        regularizer = row.regularizer(ours, diag_approx(model, data, mujoco.mjtConstraint.mjCNSTR_EQUALITY, 0)[0])
        assert np.isclose(row.stiffness, stiffness, rtol=1e-12) and np.isclose(row.damping, damping, rtol=1e-12)
        assert abs(ours - imp) < 1e-12 and np.isclose(regularizer, data.efc_R[0], rtol=1e-12)


def _one_step_errors(result, model, states) -> list[float]:
    """The worst first-step velocity error from each (shift of the first joint, joint velocities) state."""
    errors = []
    for shift, qvel in states:
        qpos = model.qpos0.copy()
        qpos[0] += shift
        errors.append(float(one_step(result, model, qpos, qvel).max()))
    return errors


def _states(shift: float, speeds=(0.0, 1.0, 3.0), nv: int = 4):
    rng = np.random.default_rng(0)
    return [(shift, speed * rng.standard_normal(nv)) for speed in speeds for _ in range(2)]


def _rollout(result, model, data, steps: int) -> float:
    """Step both simulators from their current states; the worst |qpos| difference."""
    return float(paired_rollout(result, model, data, steps).qpos.max())


def test_the_first_step_of_a_closed_loop_matches_mujoco():
    result = MJCFLoader().load(FIXTURE)
    assert [e.kind for e in result.equalities] == ["D6 joint"] and result.controller.term("equalities").connects
    errors = _one_step_errors(result, result.model, _states(0.0) + _states(1e-4, speeds=(0.0,)))
    assert max(errors) < ONE_STEP, errors


def test_a_falling_loop_follows_mujoco_for_half_a_second():
    result = MJCFLoader().load(FIXTURE)
    model = result.model
    data = mujoco.MjData(model)
    result.reset()
    worst = _rollout(result, model, data, 250)
    assert worst < ROLLOUT, worst


def test_rows_read_on_the_links_drifted_velocities_miss_the_falling_loop(monkeypatch):
    """The mutation: the links' velocities as PhysX leaves them after a step, not the ones the joints imply."""
    monkeypatch.setattr("loader.runtime.controller.refresh_link_velocities", lambda articulations: None)
    result = MJCFLoader().load(FIXTURE)
    model = result.model
    data = mujoco.MjData(model)
    result.reset()
    assert _rollout(result, model, data, 250) > ROLLOUT


def test_without_the_centripetal_term_the_first_step_misses(monkeypatch):
    """The mutation: PhysX's step leaves w x (w x r) out of the row's velocity change; without it in the target,
    a moving loop fails (measured 5.6e-3 at 1 rad/s)."""
    monkeypatch.setattr(SoftConnect, "centripetal", staticmethod(lambda *args: np.zeros(3)))
    result = MJCFLoader().load(FIXTURE)
    assert max(_one_step_errors(result, result.model, _states(0.0))) > 10 * ONE_STEP


def test_taking_both_ends_at_the_pin_matters_for_an_open_moving_loop(monkeypatch):
    """The D6 measures both ends at the pin. The mutation: the ends' centre-of-mass velocities instead."""
    states = _states(0.002, speeds=(1.0, 3.0))
    result = MJCFLoader().load(FIXTURE)
    corrected = _one_step_errors(result, result.model, states)

    def own_anchors(child, parent, pin):
        return child.velocity - parent.velocity

    monkeypatch.setattr(SoftConnect, "measured", staticmethod(own_anchors))
    result = MJCFLoader().load(FIXTURE)
    uncorrected = _one_step_errors(result, result.model, states)
    assert sum(uncorrected) > 1.5 * sum(corrected), (corrected, uncorrected)


def test_the_rigid_joint_it_replaces_misses_mujocos_soft_loop(monkeypatch):
    result = MJCFLoader().load(FIXTURE)
    for connect in result.controller.term("equalities").connects:
        connect.lock(result.model.opt.timestep)
    monkeypatch.setattr(SoftConnect, "update", lambda self, timestep: None)  # set_ctrl keeps it rigid
    errors = _one_step_errors(result, result.model, _states(1e-4, speeds=(0.0, 1.0)))
    assert max(errors) > 10 * ONE_STEP, errors


def _anchor(link, anchor: np.ndarray) -> np.ndarray:
    pose = link.entity_pose
    return pose.to_transformation_matrix()[:3, :3] @ anchor + pose.p


def test_after_release_the_loop_stays_closed_without_set_ctrl():
    """`release` hands the joints to a caller that never calls set_ctrl: the D6 locks again (the soft target of
    the last set_ctrl, held, lets the loop drift open)."""
    for release in (True, False):
        result = MJCFLoader().load(FIXTURE)
        if release:
            result.release()
        connect = result.controller.term("equalities").connects[0]
        for _ in range(500):
            result.scene.step()
        gap = np.linalg.norm(
            _anchor(connect.child, connect.child_anchor) - _anchor(connect.parent, connect.parent_anchor)
        )
        assert (gap < 1e-4) == release, (release, gap)


def test_the_connects_rows_count_in_the_solver_iterations():
    """A connect's three damped rows join its articulation's Gauss-Seidel system (loader/plan/solver_iterations.py)."""
    result = MJCFLoader().load(FIXTURE)
    weights, joints = result.controller.drive_weights(), [e.joint for e in result.equalities if e.kind == "D6 joint"]
    with_rows = drive_radii(result.model, weights, joints, result.mapping)
    without = drive_radii(result.model, weights, [], result.mapping)
    assert with_rows and with_rows.get(0, 0.0) > without.get(0, 0.0)


def _gripper_one_step_worst(damping: bool) -> float:
    """The 2f85's linkage (two connects and a joint coupling) under a sinusoidal ctrl from a start settled onto
    its loops, contacts and limits off on both sides: the worst first-step error over 60 sampled states."""
    spec = mujoco.MjSpec.from_file(str(menagerie_root() / "robotiq_2f85_v4/2f85.xml"))
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT
    if not damping:
        for joint in spec.joints:
            joint.damping = np.zeros(3)
    model = spec.compile()
    result = MJCFLoader().load(spec)
    data, probe = mujoco.MjData(model), mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    data.qvel[:] = 0.0
    worst = 0.0
    for step in range(300):
        data.ctrl[:] = 100.0 + 100.0 * np.sin(0.02 * step)
        if step % 5 == 0:
            worst = max(
                worst, float(one_step(result, model, data.qpos, data.qvel, data.ctrl, data=probe, advance=False).max())
            )
        mujoco.mj_step(model, data)
    return worst


@pytest.mark.skipif(menagerie_root() is None, reason="the Menagerie slice is not installed")
def test_the_grippers_loops_are_left_off_mujoco_by_their_joint_damping():
    """What keeps the 2f85's actuated and dynamics tiers failing: MuJoCo solves a constraint with M and
    integrates joint damping afterwards with M + dt D, PhysX solves both together. Measured: 1.9e-2 rad/s with
    the drivers' damping (0.1 on armature 0.005), 1.1e-4 with every joint's damping removed on both sides."""
    assert _gripper_one_step_worst(damping=True) > 5e-3
    assert _gripper_one_step_worst(damping=False) < 5e-4


EDGE_CASES = {
    # the world as body1: SAPIEN takes the world only as the D6's first end, the law is odd in r and v
    "world first": '<body name="a" pos="0 0 1"><joint axis="0 1 0"/><geom size=".1" pos=".3 0 0"/></body>'
    '</worldbody><equality><connect body1="world" body2="a" anchor=".3 0 1"/>',
    # a body of the static actor with a pose of its own: its anchor is in its frame, not the world's
    "static body": '<body name="s" pos="0 0 1" euler="0 0 90"><geom size=".05"/></body><body name="a" pos="0 0 1">'
    '<joint axis="0 1 0"/><geom size=".1" pos=".3 0 0"/></body></worldbody><equality>'
    '<connect body1="a" body2="s" anchor=".3 0 0"/>',
    # a floating body hung from the world by its edge
    "free body": '<body name="a" pos="0 0 1"><freejoint/><geom size=".1"/></body></worldbody><equality>'
    '<connect body1="a" body2="world" anchor=".1 0 0"/>',
}


@pytest.mark.parametrize("name", sorted(EDGE_CASES))
def test_a_connect_to_the_world_or_a_static_body_follows_mujoco(name):
    spec = mujoco.MjSpec.from_string(f"<mujoco><worldbody>{EDGE_CASES[name]}</equality></mujoco>")
    model = spec.compile()
    data = mujoco.MjData(model)
    result = MJCFLoader().load(spec)
    worst = _rollout(result, model, data, 200)
    assert worst < ROLLOUT, worst  # measured 7.9e-7 (world, static body), 3.0e-6 (free body)


def test_a_connect_between_two_static_bodies_is_listed_not_built():
    spec = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><body name="s" pos="0 0 1"><geom size=".05"/></body><body name="t" pos="0 0 2">'
        '<geom size=".05"/></body><body name="a"><joint axis="0 1 0"/><geom size=".1"/></body></worldbody>'
        '<equality><connect body1="t" body2="s" anchor="0 0 0"/></equality></mujoco>'
    )
    result = MJCFLoader().load(spec)
    assert [(e.mapped, e.reason) for e in result.equalities] == [
        (False, "joins two bodies fixed to the world: it constrains no degree of freedom")
    ]
    assert any(entry.kind == "equality" for entry in result.unsupported)


WELD = Path(__file__).resolve().parents[1] / "corpus" / "fixtures" / "welded_legs.xml"
# measured on the welded legs (hinges about three axes, anchor off the foot, torquescale 2): first step 3.1e-7 and
# 1.8e-6 rad/s at 1 and 3 rad/s, 0.5 s from qpos0 4.8e-7 rad


def _weld_states(speeds=(0.0, 1.0, 3.0)):
    return _states(0.0, speeds, nv=8)


def test_a_welds_first_step_and_half_second_match_mujoco():
    result = MJCFLoader().load(WELD)
    assert max(_one_step_errors(result, result.model, _weld_states())) < ONE_STEP
    model, data = result.model, mujoco.MjData(result.model)
    result.reset()
    worst = _rollout(result, model, data, 250)
    assert worst < ROLLOUT, worst


def test_without_the_rotation_frames_rate_a_moving_weld_misses(monkeypatch):
    """The mutation: the rates of G and R2^T in the rotational rows' J' qdot (measured 6.8e-3 at 1 rad/s without)."""
    monkeypatch.setattr(SoftWeld, "frame_rate", staticmethod(lambda *args: np.zeros(3)))
    result = MJCFLoader().load(WELD)
    assert max(_one_step_errors(result, result.model, _weld_states((1.0,)))) > 10 * ONE_STEP


def test_a_weld_without_its_rotational_rows_lets_the_feet_turn(monkeypatch):
    """What the loader did before: a D6 whose translation and twist are locked leaves swing free in PhysX (SAPIEN
    sets no motion for a cone limit); here: the rotational rows dropped, the feet's relative rotation drifts."""

    def translation_only(self, child, parent, imp, timestep, rotation):
        self.drive.set_drive_property_slerp(0.0, 0.0, 1e30, "force")
        return np.zeros(3)

    monkeypatch.setattr(SoftWeld, "angular_target", translation_only)
    result = MJCFLoader().load(WELD)
    assert max(_one_step_errors(result, result.model, _weld_states((0.0, 1.0)))) > 10 * ONE_STEP


def _released_weld_angles() -> tuple[float, float]:
    """1 s without set_ctrl after release: the feet's relative rotation angle in SAPIEN and in MuJoCo."""
    result = MJCFLoader().load(WELD)
    model, data = result.model, mujoco.MjData(result.model)
    result.release()
    paired_rollout(result, model, data, 500, set_ctrl=False)
    links = {link.name: link for link in result.articulations[0].links}
    left, right = (np.asarray(links[n].entity_pose.q) for n in ("left_lower", "right_lower"))
    mujoco_angle = 2 * np.arccos(
        min(1.0, abs(float(np.dot(data.xquat[model.body("left_lower").id], data.xquat[model.body("right_lower").id]))))
    )
    return 2 * np.arccos(min(1.0, abs(float(np.dot(left, right))))), mujoco_angle


def test_after_release_a_weld_keeps_its_relative_rotation():
    """Without set_ctrl the slerp drive holds the weld as MuJoCo's closed-loop spring-damper; PhysX's D6 alone
    cannot lock swing. Measured 8.8e-3 rad against MuJoCo's 4.8e-3."""
    sapien_angle, mujoco_angle = _released_weld_angles()
    assert abs(sapien_angle - mujoco_angle) < 1e-2, (sapien_angle, mujoco_angle)


def test_a_released_weld_without_its_rotation_spring_turns(monkeypatch):
    """The mutation: release locks only the translation (the D6 leaves swing free); measured 5.1e-2 rad against
    4.8e-3."""
    monkeypatch.setattr(SoftWeld, "lock", SoftConnect.lock)
    sapien_angle, mujoco_angle = _released_weld_angles()
    assert abs(sapien_angle - mujoco_angle) > 1e-2, (sapien_angle, mujoco_angle)


SWITCHED = """<mujoco><option timestep="0.002"/><worldbody><body name="arm" pos="0 0 1">
  <joint axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".3"/></body></worldbody>
  <equality><connect name="pin" body1="arm" body2="world" anchor=".3 0 0" active="false"/></equality></mujoco>"""


def test_switching_a_connect_on_and_off_follows_mujocos_eq_active():
    """MuJoCo's data.eq_active, switched at the same steps on both sides: the arm falls, is caught 0.02 s later
    (0.01 rad open) and let go again. Measured: 2.3e-8 before, 4e-6 caught, 2e-6 after."""
    spec = mujoco.MjSpec.from_string(SWITCHED)
    model = spec.compile()
    data = mujoco.MjData(model)
    result = MJCFLoader().load(spec)
    assert [(e.mapped, result.controller.soft_joint(e.index).active) for e in result.equalities] == [(True, False)]
    worst = {"before": _rollout(result, model, data, 10)}
    data.eq_active[0] = 1
    result.set_equality_active("pin", True)
    worst["caught"] = _rollout(result, model, data, 290)
    data.eq_active[0] = 0
    result.set_equality_active(0, False)
    worst["after"] = _rollout(result, model, data, 200)
    assert max(worst.values()) < ROLLOUT, worst
    result.reset()
    assert not result.controller.soft_joint(0).active  # back to eq_active0


def test_a_joint_coupling_switches_as_eq_active_does_in_mujoco():
    """A joint coupling switched off in both simulators: SAPIEN follows MuJoCo. Mutation: switched off in MuJoCo
    only."""
    from support.lockstep import contact_free, paired_rollout

    def run(switch_sapien: bool) -> float:
        result, model = contact_free(FIXTURE.parents[2] / "tests" / "fixtures" / "coupled_joints.xml")
        data = mujoco.MjData(model)
        data.eq_active[0] = 0
        if switch_sapien:
            result.set_equality_active(0, False)
        return float(
            paired_rollout(
                result, model, data, 500, lambda step, data: np.array([np.sin(step * 0.01), 0.3 * np.cos(step * 0.005)])
            ).qpos.max()
        )

    assert run(switch_sapien=True) < 1e-5
    assert run(switch_sapien=False) > 1e-3
    result = MJCFLoader().load(FIXTURE.parents[2] / "tests" / "fixtures" / "coupled_joints.xml")
    result.set_equality_active(0, False)
    result.reset()  # as mj_resetData: the coupling back to eq_active0 in MuJoCo's copy too
    assert result.controller.term("rows").data.eq_active[0] == result.model.eq_active0[0] == 1
    with pytest.raises(KeyError):
        result.set_equality_active("no such equality", True)
