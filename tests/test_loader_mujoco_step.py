"""`Controller.use_mujoco_step`: the joint forces of MuJoCo's own step at SAPIEN's state, written as `qf`
(loader/runtime/mujoco_step.py). MuJoCo is the oracle: over 0.5 s of a sine on every ctrl, contacts off, the
rollout follows MuJoCo's under PhysX's PGS and TGS solvers, and a mistake in the law's parts (the bias, the rows,
the integrator) does not."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
import sapien
from support.corpus import FIXTURES, menagerie_root, mjcf_file, suite_path
from support.lockstep import replay

from loader import MJCFLoader
from loader.runtime import mujoco_step
from loader.runtime.rows import RowTerm

# rad, the largest |SAPIEN - MuJoCo| joint position over 0.5 s, contacts off (mujoco 3.17.0, sapien 3.0.3), PGS / TGS:
# folding_servo_arm 5.1e-7 / 2.3e-5, coupled_joints 2.6e-7 / 1.9e-6, cheetah 4.0e-7 / 6.0e-7,
# light_damped_link_past_its_end 2.0e-6 / 3.1e-5, Menagerie panda 5.7e-7 / 1.2e-5 (the terms: the same to two
# digits, TGS: 2.3e-5, 1.9e-6, 6.0e-7, 3.1e-5, 1.2e-5)
TOLERANCE = 1e-4


def _scene(model: mujoco.MjModel, tgs: bool):
    previous = sapien.physx.get_scene_config()
    sapien.physx.set_scene_config(gravity=model.opt.gravity, enable_tgs=tgs)
    try:
        scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    finally:
        sapien.physx.set_scene_config(previous)
    scene.timestep = float(model.opt.timestep)
    return scene


def _load(path, tgs: bool = False):
    model = mujoco.MjModel.from_xml_path(str(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return MJCFLoader().set_scene(_scene(model, tgs)).load(str(path))


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


def _panda():
    root = menagerie_root()
    marks = [] if root else [pytest.mark.skip(reason="Menagerie slice not installed (extra 'menagerie')")]
    return pytest.param(root / "franka_emika_panda/panda.xml" if root else None, id="menagerie/panda", marks=marks)


MODELS = [
    pytest.param(FIXTURES / "folding_servo_arm.xml", id="folding_servo_arm"),  # stiff servos, implicitfast
    pytest.param(FIXTURES / "coupled_joints.xml", id="coupled_joints"),  # joint couplings as MuJoCo's rows
    pytest.param(suite_path("cheetah"), id="suite/cheetah"),  # Euler with joint damping, springs
    pytest.param(FIXTURES / "light_damped_link_past_its_end.xml", id="light_damped_link"),  # a limit row, light link
    _panda(),  # position servos with forceranges, finger slides on a turning hand
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
    monkeypatch.setattr(RowTerm, "joint_rows", lambda self: np.zeros(self.lent.model.nv))


def _explicit(monkeypatch):
    integrators = {**mujoco_step.INTEGRATORS, int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mujoco.mj_Euler}
    monkeypatch.setattr(mujoco_step, "INTEGRATORS", integrators)


@pytest.mark.parametrize(
    ("mistake", "path"),
    [
        pytest.param(_without_bias, FIXTURES / "folding_servo_arm.xml", id="bias_left_out"),  # 9.1e-3
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
  <option integrator="RK4"/>
  <worldbody>
    <body><joint name="h" axis="0 1 0" range="-1 1"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
  </worldbody>
  <actuator><motor joint="h"/></actuator>
</mujoco>
"""


def test_where_mujoco_step_cannot_drive_the_terms_run(tmp_path):
    """Each reason the terms run all the same, and MuJoCo's step back once the reason is gone."""
    floating = _load(suite_path("humanoid")).controller
    assert "free or ball" in floating.use_mujoco_step()
    assert "RK4" in _load(mjcf_file(tmp_path, RK4)).controller.use_mujoco_step()
    unlimited = RK4.replace('range="-1 1"', "").replace('integrator="RK4"/>', '><flag contact="disable"/></option>')
    rowless = mjcf_file(tmp_path, unlimited, "rowless.xml")
    assert "no constraint rows" in _load(rowless).controller.use_mujoco_step()
    result = _load(FIXTURES / "folding_servo_arm.xml")
    controller = result.controller
    assert controller.use_mujoco_step() is None
    with controller.without("rows"):
        assert "switched off" in controller.use_mujoco_step()
    assert controller.use_mujoco_step() is None
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
    assert all(joint.stiffness == 0 and joint.damping == 0 for joint in joints)
