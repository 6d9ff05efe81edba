"""Couplings: joint equalities, finger tendons and closed linkages under the same ctrl on both sides.

MuJoCo's soft joint equality rides on a PhysX tendon spring (loader/build/equalities.py), connects on D6 joints;
contact is off on both sides.
"""

from __future__ import annotations

import numpy as np
import pytest
from support.corpus import FIXTURES, menagerie_root
from support.lockstep import contact_free, replay

COUPLING_TOLERANCE = 1e-2  # rad, measured 4.4e-3 (soft equality)


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


@pytest.mark.parametrize("edit", [('gear="2"', 'gear="-2"'), ('polycoef="0 2 0 0 0"', 'polycoef="0 0.5 0 0 0"')],
                         ids=["gear sign", "inverted coupling ratio"])
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
    assert sorted(e.kind for e in result.equalities) == ["D6 joint", "D6 joint", "MuJoCo row"]
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
