"""MuJoCo's step under the settings of MuJoCo Playground's exported robots: one solver iteration and explicit
damping (loader/runtime/rows.py, loader/runtime/stiffness.py).

With `iterations="1"` MuJoCo integrates its solver's unconverged acceleration: the force that moves the robot is
M (qacc - qacc_smooth), not `qfrc_constraint`, it can push the free joint, and the next solve starts from this
step's qacc. With `eulerdamp` disabled MuJoCo's joint damping is explicit. The fixture throws a floating body with
frictional, damped legs under position servos; each deliberate mistake below puts SAPIEN's joints far from MuJoCo's.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from support.lockstep import at_keyframe, paired_rollout

FIXTURE = Path(__file__).parents[1] / "corpus" / "fixtures" / "one_iteration_legs.xml"
STEPS = 250  # 1 s
# m/s or rad/s, any DoF, over STEPS. Measured (mujoco 3.17.0, sapien 3.0.3): 1.2e-5. Applying qfrc_constraint
# instead of MuJoCo's acceleration 167; the free joint's share left out 0.12; the solve started cold every step
# 6.4; the damping left implicit in the drives 10.
TOLERANCE = 1e-4
IMPLICIT_STEPS = 25  # the eulerdamp variant: 2.9e-5 at 25 steps; taking the solver's qacc there 81


def _swinging(step: int, data: mujoco.MjData) -> np.ndarray:
    return 0.8 * np.sin(0.04 * step + np.arange(data.ctrl.size))


def _worst_velocity(mutate=None, path: Path = FIXTURE, steps: int = STEPS) -> float:
    result, model, data = at_keyframe(path)
    if mutate:
        mutate(result.controller)
    return float(paired_rollout(result, model, data, steps, _swinging).qvel.max())


def _constraint_force(controller) -> None:
    rows = controller.edit("rows")
    rows.joint_rows = lambda: rows.data.qfrc_constraint


def _cold_start(controller) -> None:
    rows = controller.edit("rows")
    solve = rows.contribute

    def cold(step):
        solve(step)
        rows.data.qacc_warmstart[:] = 0.0

    rows.contribute = cold


class _LeftOut:
    """The deliberate mistake: the free joint's share of the rows' force never pushes the root."""

    applied = ()

    def __call__(self, data, force, links) -> None:
        pass


def _root_left_out(controller) -> None:
    controller.edit("rows").push = _LeftOut()


def _implicit_damping(controller) -> None:
    controller.edit("stiffness").explicit_damping = False


def test_an_unconverged_solve_applies_mujocos_acceleration():
    assert _worst_velocity() < TOLERANCE
    assert _worst_velocity(_constraint_force) > 10 * TOLERANCE
    assert _worst_velocity(_cold_start) > 10 * TOLERANCE


def test_an_unconverged_solve_pushes_the_free_joint_as_mujoco_does():
    assert _worst_velocity(_root_left_out) > 10 * TOLERANCE


def test_explicit_damping_is_mujocos():
    assert _worst_velocity(_implicit_damping) > 10 * TOLERANCE


def test_an_implicit_step_integrates_the_constraint_force(tmp_path):
    """With implicit damping (Euler with `eulerdamp`, implicitfast) MuJoCo solves for the acceleration from
    `qfrc_constraint`: there the solver's unconverged qacc is not what it integrates. (This variant is chaotic in
    MuJoCo itself after about 30 steps: float32 rounding of its state moves it 0.015 m/s by step 40.)"""
    path = tmp_path / "implicit.xml"
    path.write_text(FIXTURE.read_text().replace('<flag eulerdamp="disable"/>', ""))
    assert _worst_velocity(path=path, steps=IMPLICIT_STEPS) < TOLERANCE

    def accelerated(controller):
        controller.edit("rows").accelerated = True

    assert _worst_velocity(accelerated, path=path, steps=IMPLICIT_STEPS) > 10 * TOLERANCE
