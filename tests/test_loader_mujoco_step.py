"""`Controller.use_mujoco_step`: the joint forces of MuJoCo's own step at SAPIEN's state, written as `qf`
(loader/runtime/mujoco_step.py). MuJoCo is the oracle: over 0.5 s of a sine on every ctrl, contacts off, the
rollout follows MuJoCo's under PhysX's PGS and TGS solvers, and a mistake in the law's parts (the bias, the rows,
the integrator) does not."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, menagerie_root, mjcf_file, suite_path
from support.lockstep import replay, solver_scene

from loader import MJCFLoader
from loader.runtime import mujoco_step
from loader.runtime.rows import RowTerm

# rad, the largest |SAPIEN - MuJoCo| joint position over 0.5 s, contacts off (mujoco 3.17.0, sapien 3.0.3), PGS / TGS:
# folding_servo_arm 5.1e-7 / 2.3e-5, coupled_joints 2.6e-7 / 1.9e-6, cheetah 4.0e-7 / 6.0e-7,
# light_damped_link_past_its_end 2.0e-6 / 3.1e-5, Menagerie panda 5.7e-7 / 1.2e-5 (the terms: the same to two
# digits, TGS: 2.3e-5, 1.9e-6, 6.0e-7, 3.1e-5, 1.2e-5)
# the compensated arms over 1 s: full 1.5e-15, half 9.3e-7, over 1.6e-6; the gravity PhysX lacks left out 2.7
TOLERANCE = 1e-4


def _load(path, tgs: bool = False):
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return MJCFLoader().set_scene(solver_scene(model, tgs)).load(str(path))


def _rollout(path, tgs: bool) -> float:
    """The worst joint position difference over 0.5 s of a sine on every ctrl, MuJoCo's step driving SAPIEN."""
    result = _load(path, tgs)
    assert result.controller.use_mujoco_step() is None
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    rates = 2 * np.pi * model.opt.timestep * np.arange(1, model.nu + 1)
    base = model.key_ctrl[0].copy() if model.nkey else np.zeros(model.nu)
    worst = replay(result, model, lambda step, data: base + 0.5 * np.sin(rates * step), 0.5)
    assert result.controller.whole is not None
    return float(worst.max())


def _menagerie(source: str, name: str):
    root = menagerie_root()
    marks = [] if root else [pytest.mark.skip(reason="Menagerie slice not installed (extra 'menagerie')")]
    return pytest.param(root / source if root else None, id=f"menagerie/{name}", marks=marks)


MODELS = [
    pytest.param(FIXTURES / "folding_servo_arm.xml", id="folding_servo_arm"),  # stiff servos, implicitfast
    pytest.param(FIXTURES / "coupled_joints.xml", id="coupled_joints"),  # joint couplings as MuJoCo's rows
    pytest.param(suite_path("cheetah"), id="suite/cheetah"),  # Euler with joint damping, springs
    pytest.param(FIXTURES / "light_damped_link_past_its_end.xml", id="light_damped_link"),  # a limit row, light link
    _menagerie(
        "franka_emika_panda/panda.xml", "panda"
    ),  # position servos with forceranges, finger slides on a turning hand
]


@pytest.mark.parametrize("tgs", [False, True], ids=["pgs", "tgs"])
@pytest.mark.parametrize("path", MODELS)
def test_mujoco_step_follows_mujoco(path, tgs):
    assert _rollout(path, tgs) < TOLERANCE


def _without_bias(monkeypatch):
    contribute = mujoco_step.MujocoStep.contribute

    def mistaken(self, step):
        contribute(self, step)
        step.force[self.rows.scalar] -= self.rows.data.qfrc_bias
        self.writer.write_qf(step)

    monkeypatch.setattr(mujoco_step.MujocoStep, "contribute", mistaken)


def _without_rows(monkeypatch):
    """The solve's constraint force zeroed before MuJoCo's integrator reads it."""
    solve = mujoco_step.solve

    def rowless(model, data, *args):
        solve(model, data, *args)
        data.qfrc_constraint[:] = 0.0

    monkeypatch.setattr(mujoco_step, "solve", rowless)


def _explicit(monkeypatch):
    integrators = {**mujoco_step.INTEGRATORS, int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mujoco.mj_Euler}
    monkeypatch.setattr(mujoco_step, "INTEGRATORS", integrators)


@pytest.mark.parametrize(
    ("mistake", "path"),
    [
        pytest.param(_without_bias, suite_path("cheetah"), id="bias_left_out"),  # 1.4
        pytest.param(_without_rows, FIXTURES / "coupled_joints.xml", id="rows_left_out"),  # 1.3
        pytest.param(_explicit, FIXTURES / "folding_servo_arm.xml", id="implicitfast_as_euler"),  # not finite
    ],
)
def test_a_mistake_in_the_law_leaves_mujoco(mistake, path, monkeypatch):
    mistake(monkeypatch)
    worst = _rollout(path, tgs=False)
    assert not worst < 10 * TOLERANCE


RK4 = """
<mujoco>
  <option integrator="RK4"><flag contact="disable"/></option>
  <worldbody>
    <body><joint name="h" axis="0 1 0" damping=".5"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
  </worldbody>
  <actuator><motor joint="h"/></actuator>
</mujoco>
"""


def test_a_model_without_rows_on_rk4_is_stepped_by_mujocos_euler(tmp_path):
    """A damped pendulum with no constraint row (no limit, contacts off) on RK4: MuJoCo's step runs on a copy made
    for it and, as the terms do, takes RK4 as Euler, whose run it follows. Mutation: Euler's implicit damping taken as
    explicit (its solver's qacc integrated): 5.4e-3 rad, against 3.7e-7."""
    path = mjcf_file(tmp_path, RK4)
    result = _load(path)
    assert result.controller.use_mujoco_step() is None
    model = result.model
    euler = mujoco.MjModel.from_xml_path(str(path))
    euler.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER

    def worst(result) -> float:
        return float(replay(result, model, lambda step, data: np.sin(0.05 * step), 0.5, reference=euler).max())

    assert worst(result) < TOLERANCE
    mistaken = _load(path)
    mistaken.controller.use_mujoco_step()
    mistaken.set_ctrl(None)
    whole = mistaken.controller.whole  # as if Euler integrated the solver's qacc here: damping explicit, no drive
    whole.accelerated, whole.damped_joints, whole.zeroed = True, [], False
    whole.damping[:] = 0.0
    assert worst(mistaken) > 10 * TOLERANCE


@pytest.mark.parametrize("law, mistake", [("mujoco_step", None), ("terms", None), ("terms", "damping_implicit")])
def test_rk4_without_eulerdamp_damps_explicitly_under_either_law(tmp_path, monkeypatch, law, mistake):
    """The damped pendulum on RK4 with `eulerdamp` disabled: the loader simulates RK4 as Euler, whose damping is then
    explicit, so both laws follow MuJoCo's Euler without implicit damping. Mutation: the damping rule reading RK4 as
    implicit, as it did for the terms (`mj.explicit_damping`); MuJoCo's own step gives v1 whatever its drives hold."""
    from loader.model import mj

    if mistake:
        monkeypatch.setattr(mj, "EULER_LIKE", (int(mujoco.mjtIntegrator.mjINT_EULER),))
    path = mjcf_file(
        tmp_path, RK4.replace('<flag contact="disable"/>', '<flag contact="disable" eulerdamp="disable"/>')
    )
    result = _load(path)
    result.controller.use_mujoco_step(law == "mujoco_step")
    euler = mujoco.MjModel.from_xml_path(str(path))
    euler.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    worst = float(replay(result, result.model, lambda step, data: np.sin(0.05 * step), 0.5, reference=euler).max())
    assert (worst < TOLERANCE) == (mistake is None), worst


def _pushed_then_let_go(path) -> float:
    """The worst joint position difference over 0.5 s from qpos0, the caller's `qfrc_applied` on every DoF for the
    first 0.1 s and none after, zero ctrl, contacts off: MuJoCo's step driving SAPIEN against MuJoCo."""
    result = _load(path)
    assert result.controller.use_mujoco_step() is None
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    result.set_state(data.qpos, data.qvel)
    push, worst = np.full(model.nv, 0.2), 0.0
    for step in range(round(0.5 / model.opt.timestep)):
        applied = push if step * model.opt.timestep < 0.1 else None
        data.qfrc_applied[:] = 0.0 if applied is None else applied
        result.set_ctrl(np.zeros(model.nu), qfrc_applied=applied)
        result.scene.step()
        mujoco.mj_step(model, data)
        worst = max(worst, float(np.abs(result.get_state()[0] - data.qpos).max()))
    return worst


def test_a_force_applied_for_a_while_then_none_is_mujocos_too(monkeypatch):
    """MuJoCo's copy takes the caller's `qfrc_applied` while it is given and none once it is not (the copy's own
    force cleared once, not every step): 7.1e-8 rad. Mutation: the copy keeps the last force it was given (0.82 rad)."""
    path = FIXTURES / "coupled_joints.xml"
    assert _pushed_then_let_go(path) < TOLERANCE
    mirror = RowTerm.mirror_state

    def keeps_the_force(self, step):
        mirror(self, step)
        self.applying = False  # as if the force had been cleared: it stays in the copy

    monkeypatch.setattr(RowTerm, "mirror_state", keeps_the_force)
    assert _pushed_then_let_go(path) > 10 * TOLERANCE


@pytest.mark.parametrize("upper, lower", [(1, 1), (0.5, 1), (1, 1.5)], ids=["full", "half", "over"])
def test_a_compensated_arm_follows_mujoco_under_its_step(tmp_path, monkeypatch, upper, lower):
    """PhysX's gravity is off on a fully compensated link (`gravcomp.py`), where MuJoCo's bias keeps it and its
    gravcomp force cancels it: the step's joint forces add its J^T m g back (`MujocoStep.gravity_physx_lacks`). A
    link compensated partly or more than fully keeps PhysX's gravity. Mutation: that gravity left out (the fully
    compensated arm flies up)."""
    from support.lockstep import no_ctrl
    from test_loader_passive import GRAVCOMP

    path = mjcf_file(tmp_path, GRAVCOMP.format(upper=upper, lower=lower), "gravcomp.xml")
    result = _load(path)
    assert result.controller.law() == "mujoco_step"
    assert replay(result, result.model, no_ctrl, 1.0).max() < TOLERANCE
    monkeypatch.setattr(mujoco_step, "unpulled", lambda *args: [])
    mistaken = _load(path)
    assert replay(mistaken, mistaken.model, no_ctrl, 1.0).max() > 10 * TOLERANCE


def test_where_mujoco_step_cannot_drive_the_terms_run():
    """Each reason the terms run all the same, and MuJoCo's step back once the reason is gone."""
    floating = _load(suite_path("humanoid")).controller
    assert "free or ball" in floating.use_mujoco_step()
    result = _load(FIXTURES / "folding_servo_arm.xml")
    controller = result.controller
    assert controller.use_mujoco_step() is None
    with controller.without("rows"):
        assert "switched off" in controller.use_mujoco_step()
    assert controller.use_mujoco_step() is None
    with controller.on_terms():  # the terms for a while, MuJoCo's step back after
        assert controller.law() == "terms: asked for (set_ctrl_law)"
    assert controller.law() == "mujoco_step"
    result.disable_actuators()  # the copy's actuation off: still MuJoCo's step
    assert controller.whole is not None
    result.disable_actuators(False)
    controller.edit_laws()
    assert "handed out" in controller.use_mujoco_step()
    result.set_ctrl(None)
    assert controller.whole is None


def test_mujoco_step_zeroes_the_drives_again_after_release():
    """`release()` hands the joints their passive drives; the next `set_ctrl` under MuJoCo's step takes them back to
    nothing (cheetah's joints have springs). Mutation: the release hook of `MujocoStep` left out."""
    result = _load(suite_path("cheetah"))
    assert result.controller.use_mujoco_step() is None
    result.set_ctrl(None)
    result.release()
    joints = [joint for art in result.articulations for joint in art.active_joints]
    assert any(joint.stiffness > 0 for joint in joints)
    result.set_ctrl(None)
    damping = result.controller.whole.damping
    assert [joint.stiffness for joint in result.controller.layout.joints] == [0.0] * len(damping)
    assert [joint.damping for joint in result.controller.layout.joints] == pytest.approx(damping, rel=1e-6)


def test_the_harness_judges_mujoco_step_with_the_actuated_tier(monkeypatch):
    """`run` (the loader's default law): the actuated tier passes on the stiff servo arm with MuJoCo's step driving
    it, and fails with the bias left out of the law."""
    from conformance import tolerances
    from conformance.loaders import open_with
    from conformance.tiers.actuated import actuated

    tol = tolerances.load()
    session = open_with("ours", str(FIXTURES / "folding_servo_arm.xml"))
    assert session.load_info()["set_ctrl_law"] == "mujoco_step"
    assert actuated(session.result, session.model, 0, tol).status == "pass"
    assert session.result.controller.whole is not None
    _without_bias(monkeypatch)
    session = open_with("ours", str(FIXTURES / "folding_servo_arm.xml"))
    assert actuated(session.result, session.model, 0, tol).status == "fail"


@pytest.mark.parametrize("path", [_menagerie("leap_hand/right_hand.xml", "leap_hand")])
def test_a_heavy_servo_on_a_light_link_is_held_to_mujocos_velocity(path, monkeypatch):
    """The LEAP hand's finger links are light under their servos' damping (dt D > M): with the drive holding each to
    MuJoCo's v1 its one-step velocity follows MuJoCo's within the actuated tier's tolerance (measured 8.1e-7, the
    terms 8.7e-7); with `qf` alone PhysX's float32 inertia scales the step's large velocity change (1.5e-5, over
    the 1e-5 tolerance)."""
    from conformance import tolerances
    from conformance.loaders import open_with
    from conformance.tiers.actuated import actuated

    hand, tol = str(path), tolerances.load()

    def one_step_qvel() -> float:
        session = open_with("ours", hand)
        report = actuated(session.result, session.model, 0, tol)
        return next(metric.max for metric in report.metrics if metric.name == "one_step_qvel")

    limit = tol["actuated.one_step_qvel_fixed"]
    assert one_step_qvel() < limit
    init = mujoco_step.MujocoStep.__init__

    def undamped(self, model, rows, writer, damping, layout):
        init(self, model, rows, writer, np.zeros_like(damping), layout)

    monkeypatch.setattr(mujoco_step.MujocoStep, "__init__", undamped)
    assert one_step_qvel() > limit


def test_the_terms_are_judged_against_the_manifests_expectations():
    """`--loader terms` is this project's loader: the manifest's expectations (a chaotic box stack, a known failure)
    hold for it as for `ours`, where another loader keeps only what the model itself decides."""
    from conformance import manifest
    from conformance.cli import DEFAULT_MANIFEST
    from conformance.runner import foreign

    entries = manifest.load(DEFAULT_MANIFEST).models
    assert list(foreign(entries, "terms")) == list(entries)
    stacker = next(entry for entry in entries if entry.id == "stacker")
    assert stacker.expect["contact"].outcome == "chaotic"
    (other,) = foreign([stacker], "physx")
    assert "contact" not in other.expect


def _implicit_cheetah(whole: bool) -> float:
    """Suite cheetah on MuJoCo's implicit integrator (its full velocity derivatives): the worst joint position
    difference over 0.5 s of a sine on every ctrl, contacts off, MuJoCo's step driving SAPIEN or the terms."""
    spec = mujoco.MjSpec.from_file(str(suite_path("cheetah")))
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(spec)
    result.set_contacts(False)
    assert result.controller.use_mujoco_step(whole) == (None if whole else "switched off")
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    rates = 2 * np.pi * model.opt.timestep * np.arange(1, model.nu + 1)
    return float(replay(result, model, lambda step, data: 0.5 * np.sin(rates * step), 0.5).max())


def test_mujocos_implicit_integrator_is_its_own_under_mujoco_step():
    """The terms approximate `integrator="implicit"` (as implicitfast: measured 1.3e-2 rad on suite cheetah); MuJoCo's
    step integrates with its own derivatives (2.5e-7, mujoco 3.17.0, sapien 3.0.3)."""
    assert _implicit_cheetah(whole=True) < TOLERANCE
    assert _implicit_cheetah(whole=False) > 10 * TOLERANCE


# rad, Menagerie panda under PGS over 0.5 s (its fingers slide on the turning hand): measured 7.2e-7 with those slides
# undriven, 2.3e-5 with their damping in a drive toward v1 (mujoco 3.17.0, sapien 3.0.3)
TURNING_SLIDE_TOLERANCE = 5e-6


@pytest.mark.parametrize("path", [_menagerie("franka_emika_panda/panda.xml", "panda")])
def test_a_slide_on_a_turning_link_keeps_no_drive(path, monkeypatch):
    """PhysX's drive measures a slide's velocity on a turning link short of the centripetal term, so a drive toward
    MuJoCo's v1 there pulls the fingers off it. Mutation: the slides driven like every other damped DoF."""
    assert _rollout(path, tgs=False) < TURNING_SLIDE_TOLERANCE
    monkeypatch.setattr("loader.runtime.controller.map_slides", lambda articulations: [])
    assert _rollout(path, tgs=False) > TURNING_SLIDE_TOLERANCE


# the dynamics tier's one-step qacc on the Menagerie panda with its actuators off (its servos' kv out of MuJoCo's
# implicit damping): measured 3.8e-4 with the passive damping in the drives, 8.2e-4 with the servos' kv left in (the
# terms: 2.3e-4; the tier's tolerance 2e-3) (mujoco 3.17.0, sapien 3.0.3)
ACTUATORS_OFF_QACC = 6e-4


@pytest.mark.parametrize("path", [_menagerie("franka_emika_panda/panda.xml", "panda")])
def test_the_drives_hold_the_damping_mujoco_holds_implicitly(path, monkeypatch):
    """With the actuators off MuJoCo's step damps implicitly only the joints' own damping, and so do the drives
    toward v1. Mutation: the servos' kv left in the drives."""
    from conformance import tolerances
    from conformance.loaders import open_with
    from conformance.tiers.dynamics import dynamics

    def one_step_qacc() -> float:
        session = open_with("ours", str(path))
        report = dynamics(session.result, session.model, 0, tolerances.load())
        return next(metric.max for metric in report.metrics if metric.name == "one_step_qacc")

    assert one_step_qacc() < ACTUATORS_OFF_QACC
    monkeypatch.setattr("loader.runtime.controller.Controller.implicit_laws", lambda self: self.drive_laws())
    assert one_step_qacc() > ACTUATORS_OFF_QACC
