"""The scene the loader builds into: its own, matched to the model without touching PhysX's process-global
configuration, or the caller's (`MJCFLoader().set_scene(scene)`), checked against the model and simulated at its own
timestep. MuJoCo at the scene's timestep is the oracle."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
import sapien
from support.corpus import FIXTURES, suite_path
from support.lockstep import replay

from loader import MJCFLoader, SceneMismatchWarning
from loader.plan.physx_settings import create_scene

# a joint spring and damper, a filtered actuator and a servo (drive terms), and a limit whose solref refsafe clamps
SERVO = """<mujoco model="servo"><option timestep="0.01" integrator="implicitfast"/>
  <worldbody><body pos="0 0 1"><joint name="hinge" axis="0 1 0" stiffness="40" damping="2" limited="true"
      range="-0.05 0.05" solreflimit="0.005 1"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" contype="0" conaffinity="0"/></body></worldbody>
  <actuator><general name="filtered" joint="hinge" dyntype="filter" dynprm="0.05" gainprm="8" ctrlrange="-1 1"/>
    <position joint="hinge" kp="30" kv="1"/></actuator></mujoco>"""
SCENE_TIMESTEP = 0.002  # s, a fifth of the file's
# rad over 1 s against MuJoCo at the scene's timestep: measured 3.2e-9; with the model's timestep in the mapping
# (drives, activation, limit rows) 6.3e-3, and 5.8e-3 with it left only in the limit rows
SCENE_TIMESTEP_TOLERANCE = 1e-6


def _servo_ctrl(step, data):
    t = step * SCENE_TIMESTEP
    return np.array([np.sin(7 * t), 0.5 * np.cos(5 * t)])


def test_a_scene_with_another_timestep_is_warned_and_used(tmp_path):
    (tmp_path / "servo.xml").write_text(SERVO)
    at_scene_timestep = mujoco.MjModel.from_xml_string(SERVO)
    at_scene_timestep.opt.timestep = SCENE_TIMESTEP
    scene = create_scene(at_scene_timestep)  # gravity and solver matched: only the timestep differs
    with pytest.warns(SceneMismatchWarning, match=r"its timestep is 0.002 s, the model's 0.01 s") as caught:
        result = MJCFLoader().set_scene(scene).load(tmp_path / "servo.xml")
    assert len([w for w in caught if issubclass(w.category, SceneMismatchWarning)]) == 1
    error = replay(result, result.model, _servo_ctrl, 1.0, reference=at_scene_timestep)
    assert error.max() < SCENE_TIMESTEP_TOLERANCE


def test_a_matched_scene_given_twice_is_not_warned_about():
    loader = MJCFLoader()
    loader.load(suite_path("pendulum"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneMismatchWarning)
        loader.load(suite_path("pendulum"))  # into the scene the first load made


@pytest.fixture
def distinct_global_config():
    """PhysX's process-global configuration set to values no model here asks for; restored afterwards."""
    scene_before, body_before = sapien.physx.get_scene_config(), sapien.physx.get_body_config()
    sapien.physx.set_scene_config(gravity=np.array([0.5, 0.0, -3.0], np.float32), enable_tgs=True)
    sapien.physx.set_body_config(sleep_threshold=0.25)
    yield
    sapien.physx.set_scene_config(scene_before)
    sapien.physx.set_body_config(body_before)


def test_the_loader_leaves_physx_global_configuration_as_it_found_it(distinct_global_config):
    result = MJCFLoader().load(suite_path("pendulum"))
    scene, body = sapien.physx.get_scene_config(), sapien.physx.get_body_config()
    assert (list(scene.gravity), scene.enable_tgs, body.sleep_threshold) == ([0.5, 0.0, -3.0], True, 0.25)
    own = result.scene.physx_system.config  # the loader's scene still simulates what MuJoCo does
    np.testing.assert_allclose(own.gravity, result.model.opt.gravity, atol=1e-6)
    assert own.enable_tgs is False
    assert all(art.get_sleep_threshold() == 0.0 for art in result.articulations)


def test_a_scene_with_other_gravity_or_solver_is_warned_about(distinct_global_config):
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])  # made under the distinct global configuration
    scene.timestep = 0.02  # the model's
    with pytest.warns(SceneMismatchWarning) as caught:
        MJCFLoader().set_scene(scene).load(suite_path("pendulum"))
    messages = " ".join(str(w.message) for w in caught if issubclass(w.category, SceneMismatchWarning))
    assert "its gravity is [0.5, 0.0, -3.0], the model's [0.0, 0.0, -9.8" in messages and "timestep" not in messages
    assert "TGS" not in messages  # the drives are written as joint forces (tests/test_loader_solver.py)
    ball = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    ball.timestep = 0.002
    with pytest.warns(SceneMismatchWarning) as caught:
        MJCFLoader().set_scene(ball).load(FIXTURES / "ball_joint.xml")
    messages = " ".join(str(w.message) for w in caught if issubclass(w.category, SceneMismatchWarning))
    assert "TGS solver" in messages and "ball joints" in messages and "enable_tgs=False" in messages
