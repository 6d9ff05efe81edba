"""Couplings: joint equalities, finger tendons and closed linkages under the same ctrl on both sides.

MuJoCo's soft joint equality rides on a PhysX tendon spring (loader/plan/equalities.py), connects on D6 joints;
contact is off on both sides.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, menagerie_root
from support.lockstep import contact_free, replay

COUPLING_TOLERANCE = 1e-2  # rad, measured 4.4e-3 (soft equality)


LOOP_TOLERANCE = 1e-5  # rad over 0.5 s, measured 2.0e-7; rows off (D6 locked): 3.4e-4 (mujoco 3.17.0, sapien 3.0.3)
GRIPPER_TOLERANCE = 1e-3  # rad or m, measured 3.3e-4 (5e-4 with rigid connects)


needs_menagerie = pytest.mark.skipif(menagerie_root() is None, reason="Menagerie slice not installed")


def _fixture_ctrl(step, data):
    return np.array([np.sin(step * 0.01), 0.3 * np.cos(step * 0.005)])


def test_motor_servo_and_joint_coupling_match_mujoco():
    result, model = contact_free(FIXTURES / "coupled_joints.xml")
    errors = replay(result, model, _fixture_ctrl, 2.0)
    assert errors.max() < COUPLING_TOLERANCE, errors.max()


def test_set_ctrl_clamps_to_ctrlrange():
    result, model = contact_free(FIXTURES / "coupled_joints.xml")
    errors = replay(result, model, lambda step, data: np.array([5.0, -3.0]), 0.5)
    assert errors.max() < COUPLING_TOLERANCE


@pytest.mark.parametrize(
    "edit",
    [('gear="2"', 'gear="-2"'), ('polycoef="0 2 0 0 0"', 'polycoef="0 0.5 0 0 0"')],
    ids=["gear sign", "inverted coupling ratio"],
)
def test_a_wrong_gear_sign_or_coupling_ratio_is_caught(tmp_path, edit):
    text = (FIXTURES / "coupled_joints.xml").read_text()
    assert edit[0] in text
    (tmp_path / "mutated.xml").write_text(text.replace(*edit))
    result, _ = contact_free(tmp_path / "mutated.xml")
    _, reference = contact_free(FIXTURES / "coupled_joints.xml")
    errors = replay(result, result.model, _fixture_ctrl, 2.0, reference=reference)
    assert errors.max() > 10 * COUPLING_TOLERANCE


def _closing(actuator: int, start: float, end: float, steps: int):
    def ctrl_at(step, data):
        ctrl = data.ctrl.copy()
        ctrl[actuator] = start + (end - start) * min(1.0, step / (steps / 2))
        return ctrl

    return ctrl_at


@needs_menagerie
def test_panda_finger_tendon_and_equality_hold_while_closing():
    result, model = contact_free(menagerie_root() / "franka_emika_panda/panda.xml")
    assert [e.kind for e in result.equalities] == ["MuJoCo row"]
    errors = replay(result, model, _closing(7, 255.0, 0.0, 500), 1.0)
    assert errors.max() < GRIPPER_TOLERANCE, errors.max()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos[-1] < 0.005 and abs(qpos[-1] - qpos[-2]) < 1e-4  # closed, both fingers together


@needs_menagerie
def test_robotiq_2f85_linkage_holds_while_closing():
    result, model = contact_free(menagerie_root() / "robotiq_2f85_v4/2f85.xml")
    assert [e.kind for e in result.equalities] == ["MuJoCo row"] * 3
    errors = replay(result, model, _closing(0, 0.0, 255.0, 500), 1.0)
    assert errors.max() < GRIPPER_TOLERANCE, errors.max()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos.min() > 0.8  # closed: every joint of the linkage moved with the driver


def test_single_joint_equality_holds_the_joint_at_qpos0_plus_c0(tmp_path):
    """MuJoCo's joint equality couples displacements from qpos0: alone, it holds q at qpos0 + c0 (ref = 30 deg)."""
    (tmp_path / "held.xml").write_text(
        '<mujoco><compiler angle="degree"/><option gravity="0 0 0"/><worldbody><body>'
        '<joint name="a" axis="0 0 1" ref="30"/><geom size=".1" pos=".2 0 0"/></body></worldbody>'
        '<equality><joint joint1="a" polycoef="0.2 0 0 0 0"/></equality></mujoco>'
    )
    result, model = contact_free(tmp_path / "held.xml")
    result.step(None, substeps=2000)
    qpos, _ = result.mapping.get_state(result.articulations)
    assert qpos[0] == pytest.approx(model.qpos0[0] + 0.2, abs=1e-3)


LOOPS = Path(__file__).resolve().parents[1] / "corpus" / "fixtures"


@pytest.mark.parametrize("fixture", ["closed_chain.xml", "welded_legs.xml"])
def test_a_fixed_base_loop_is_mujocos_own_row(fixture):
    """A five-bar closed by a connect, and two legs held by a weld, on fixed bases: their rows are MuJoCo's own,
    solved with the limits beside them, so a loop falling from qpos0 follows MuJoCo. Mutation: the rows term off
    (the D6 beside them stands locked, rigid where MuJoCo is soft)."""

    def run(rows: bool) -> float:
        result, model = contact_free(LOOPS / fixture)
        assert {e.kind for e in result.equalities} == {"MuJoCo row"}
        if not rows:
            result.controller.without("rows")
        return float(replay(result, model, lambda step, data: None, 0.5).max())

    assert run(rows=True) < LOOP_TOLERANCE
    assert run(rows=False) > 10 * LOOP_TOLERANCE


def test_after_release_a_fixed_base_loop_is_held_by_its_locked_d6():
    """release(): no set_ctrl, so no MuJoCo rows; the D6 that stood by locks and the loop stays closed."""
    from loader import MJCFLoader

    def violation(result) -> float:  # MuJoCo's equality rows at SAPIEN's state: how far the loop is open
        data = mujoco.MjData(result.model)
        data.qpos[:], data.qvel[:] = result.mapping.get_state(result.articulations)
        mujoco.mj_forward(result.model, data)
        rows = data.efc_type[: data.nefc] == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        return float(np.abs(data.efc_pos[: data.nefc][rows]).max())

    def opened(lock: bool) -> float:
        result = MJCFLoader().load(LOOPS / "closed_chain.xml")
        result.set_ctrl(None)
        result.release()
        if not lock:  # the mutation: the D6 left standing by
            result.controller.soft_joint(next(e.index for e in result.equalities if e.joint is not None)).stand_by()
        worst = 0.0
        for step in range(500):
            result.scene.step()
            worst = max(worst, violation(result)) if step % 10 == 0 else worst
        return worst

    assert opened(lock=True) < 1e-3
    assert opened(lock=False) > 1e-2


CARRIED_PACK = """<mujoco><option timestep="0.002" gravity="4 0 -9.81"/>
  <worldbody>
    <body name="upper"><joint name="shoulder" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="1"/>
      <body name="lower" pos="0 0 -0.3"><joint name="elbow" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="1"/></body></body>
    <body name="pack" pos="0 0 -0.45"><freejoint/><geom type="box" size=".1 .1 .05" mass="5"/></body>
  </worldbody>
  <equality><joint joint1="elbow" joint2="shoulder" polycoef="0 0.5 0 0 0"/><weld body1="pack" body2="lower"/>
  </equality>
</mujoco>"""
CARRIED_TOLERANCE = (
    1e-5  # rad over 1 s; measured 4.3e-7 as MuJoCo's rows, 0.30 as a D6 joint (mujoco 3.17.0, sapien 3.0.3)
)


def test_a_floating_body_welded_to_an_arm_is_mujocos_own_row(tmp_path, monkeypatch):
    """A 5 kg pack on a free joint welded to an arm whose elbow is coupled to its shoulder: the weld is MuJoCo's row,
    solved with the coupling, its share on the pack a wrench on the pack's root link. Mutation: the D6 form."""
    import loader.plan.equalities

    path = tmp_path / "pack.xml"
    path.write_text(CARRIED_PACK)
    result, model = contact_free(path)
    assert [e.kind for e in result.equalities] == ["MuJoCo row", "MuJoCo row"]
    errors = replay(result, model, lambda step, data: None, 1.0)
    assert errors.max() < CARRIED_TOLERANCE, errors.max()
    monkeypatch.setattr(loader.plan.equalities, "_joint_row", lambda *args: False)
    d6, model = contact_free(path)
    assert replay(d6, model, lambda step, data: None, 1.0).max() > 1e3 * CARRIED_TOLERANCE
