"""A free joint's damping and armature, and a lone free body's spin under the implicit integrators: what MuJoCo's
step adds to a floating root that PhysX's does not (loader/runtime/free_joint.py).

The fixture throws a lone damped egg-like body and a damped floating body with two legs from its keyframe. Each
deliberate mistake below (the law left out, the damping taken explicitly, the free joint's armature or the legs'
share of the correction forgotten, the implicit spin term left out) puts SAPIEN's rollout far from MuJoCo's.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from support.lockstep import at_keyframe, paired_rollout

from loader import MJCFLoader
from loader.runtime.free_joint import gyroscopic_derivative

FIXTURE = Path(__file__).parents[1] / "corpus" / "fixtures" / "damped_free_joints.xml"
STEPS = 300  # 0.6 s
# m/s or rad/s, any DoF, over STEPS. Measured (mujoco 3.17.0, sapien 3.0.3): 1.2e-5 under Euler and implicitfast.
# Without the law 5.0; the damping taken explicitly 2.8; the free joint's armature forgotten 0.86; the legs left
# where PhysX's velocity moved them 2.1e-3; implicitfast without the implicit spin term 5.4e-3. (MuJoCo's implicit
# also takes the legs' Coriolis derivative, which the loader lists as approximated: 3e-3.)
TOLERANCE = 1e-4


def _fixture(tmp_path: Path, integrator: str | None) -> Path:
    if integrator is None:
        return FIXTURE
    path = tmp_path / f"damped_{integrator}.xml"
    path.write_text(
        FIXTURE.read_text().replace(
            '<option timestep="0.002"/>', f'<option timestep="0.002" integrator="{integrator}"/>'
        )
    )
    return path


def _worst_velocity(path: Path, mutate=None) -> float:
    result, model, data = at_keyframe(path)
    if mutate:
        mutate(result.controller.edit("momentum"))
    return float(paired_rollout(result, model, data, STEPS).qvel.max())


def _without(momentum) -> None:
    momentum.law = None


def _explicit_damping(momentum) -> None:
    for _, implicit, *_ in momentum.law.roots.values():
        implicit[:] = 0.0


def _no_armature(momentum) -> None:
    for _, _, shift, _, rotational, _ in momentum.law.roots.values():
        shift[:6, :6] = 0.0  # the free joint's DoFs lead its tree's: no -A there
        rotational[:] = 0.0


def _legs_left_in_place(momentum) -> None:
    """The legs take MuJoCo's end velocity but stay where PhysX's velocity moved them."""
    law = momentum.law

    def velocities_only(art, index, change, qvel1):
        dofadr, sapien = law.scalars[index]
        v = np.asarray(art.get_qvel(), np.float64)
        v[sapien] = qvel1[dofadr]
        art.set_qvel(v.astype(np.float32))

    law._joints = velocities_only


def _no_spin_term(momentum) -> None:
    momentum.law.gyroscopic = False


@pytest.mark.parametrize("integrator", [None, "implicitfast"])
def test_damped_free_bodies_move_as_in_mujoco(tmp_path, integrator):
    assert _worst_velocity(_fixture(tmp_path, integrator)) < TOLERANCE


@pytest.mark.parametrize("mistake", [_without, _explicit_damping, _no_armature, _legs_left_in_place])
def test_each_part_of_the_law_is_needed(mistake):
    worst = _worst_velocity(FIXTURE, mistake)
    assert worst > 10 * TOLERANCE


def test_implicitfast_takes_a_lone_bodys_spin_implicitly(tmp_path):
    assert _worst_velocity(_fixture(tmp_path, "implicitfast"), _no_spin_term) > 10 * TOLERANCE


def test_the_spin_derivative_is_mujocos():
    """Against a finite difference of MuJoCo's own velocity-dependent force, at a tilted, spinning egg."""
    model = mujoco.MjModel.from_xml_path(str(FIXTURE))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    body, step = model.body("egg").id, 1e-7
    force = -data.qfrc_bias[:6].copy()
    numeric = np.zeros((6, 6))
    for i in range(6):
        nudged = mujoco.MjData(model)
        nudged.qpos[:], nudged.qvel[:] = data.qpos, data.qvel
        nudged.qvel[i] += step
        mujoco.mj_forward(model, nudged)
        numeric[:, i] = (-nudged.qfrc_bias[:6] - force) / step
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    rotation = data.xmat[body].reshape(3, 3)
    analytic = gyroscopic_derivative(
        float(model.body_mass[body]), model.body_ipos[body], rotation, mass[3:6, 3:6], data.qvel[3:6]
    )
    assert np.abs(analytic - numeric).max() < 1e-6 * np.abs(numeric).max()


MASSLESS_ROOT = """<mujoco><option timestep="0.002"/>
  <worldbody><body name="kettle" pos="-0.3 0.4 1.6"><freejoint/>
    <body name="pot"><inertial pos="-0.003 0 0.07" mass="0.9" diaginertia="0.009 0.007 0.006"/></body>
  </body></worldbody></mujoco>"""
# rad/s after 0.2 s of free fall from rest under PhysX's own step (the momentum term off: in free flight MuJoCo's root
# rows set the root's velocity whatever PhysX's inertia, but a contact hands the root to PhysX). Measured (mujoco
# 3.17.0, sapien 3.0.3): 4.8e-8 with the helper mass at the massless root's origin; 3.6e-3 with it at MuJoCo's
# body_ipos (the body's position in its parent, 2 m away).
TURNING = 1e-5


def _turning_after_a_fall(tmp_path: Path) -> float:
    path = tmp_path / "kettle.xml"
    path.write_text(MASSLESS_ROOT)
    result = MJCFLoader().load(path)
    result.controller.without("momentum")
    for _ in range(100):
        result.set_ctrl(None)
        result.scene.step()
    return float(np.abs(result.get_state()[1][3:6]).max())


def test_a_massless_root_carrying_a_heavy_child_falls_without_turning(tmp_path):
    assert _turning_after_a_fall(tmp_path) < TURNING


def test_a_helper_mass_at_mujocos_massless_ipos_turns_the_fall(tmp_path, monkeypatch):
    """The deliberate mistake: the massless root's helper mass where MuJoCo leaves its `body_ipos`."""
    import loader.model.mapping
    import loader.plan.tree

    for module in (loader.plan.tree, loader.model.mapping):
        monkeypatch.setattr(module, "centres", lambda model: model.body_ipos.copy())
    assert _turning_after_a_fall(tmp_path) > 10 * TURNING


# The fixture's roots and legs pushed by a constant qfrc_applied: force (world) and torque (body frame) on each free
# joint, torques on the hinges. Measured (mujoco 3.17.0, sapien 3.0.3), worst velocity over STEPS: 1.3e-5 m/s or
# rad/s; with the free joints' share dropped (the old `qfrc_to_sapien`) 1.07; the wrench hidden from the momentum
# settle 1.44.
APPLIED = np.array([0.02, -0.01, 0.03, 4e-4, -3e-4, 2e-4, 1.5, -2.0, 4.0, 0.3, -0.2, 0.25, 0.1, -0.05])


def _pushed_velocity(mutate=None) -> float:
    result, model, data = at_keyframe(FIXTURE)
    if mutate:
        mutate(result.controller)
    data.qfrc_applied[:] = APPLIED
    worst = 0.0
    for _ in range(STEPS):
        result.set_ctrl(None, qfrc_applied=APPLIED)
        mujoco.mj_step(model, data)
        result.scene.step()
        worst = max(worst, float(np.abs(result.get_state()[1] - data.qvel).max()))
    return worst


def _roots_dropped(controller) -> None:
    controller.pushed.roots.clear()


def _hidden_from_the_settle(controller) -> None:
    settle = controller.settle

    def blind() -> None:
        pushed = list(controller.pushed.applied)
        controller.pushed.applied.clear()
        settle()
        controller.pushed.applied.extend(pushed)

    controller.settle = blind


def test_qfrc_applied_pushes_floating_roots_as_in_mujoco():
    assert _pushed_velocity() < TOLERANCE


@pytest.mark.parametrize("mistake", [_roots_dropped, _hidden_from_the_settle])
def test_qfrc_applied_on_a_root_needs_its_wrench_and_the_settle(mistake):
    assert _pushed_velocity(mistake) > 10 * TOLERANCE
