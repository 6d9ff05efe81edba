"""A floating robot whose joints turn fast within a step: its root velocity after each PhysX step in MuJoCo's
convention (loader/runtime/momentum.py).

The fixture's two mirrored legs start past their ranges; MuJoCo's soft limits kick them out at about 10 rad/s.
PhysX conserves the articulation's momentum through its step and MuJoCo keeps qvel, so without the `momentum` term
the body's vertical speed parts from MuJoCo's within a few steps (the mutation). Tilted, with one leg's gravity
half compensated, gravity turns the robot about its centre of mass; in a fluid, drag does.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
from support.lockstep import at_keyframe, contact_free, one_step, paired_rollout

import loader.runtime.centroidal
import loader.runtime.momentum
from loader.runtime.centroidal import random_state

FIXTURE = Path(__file__).parents[1] / "corpus" / "fixtures" / "kicked_legs.xml"
# m/s or rad/s over 50 steps (0.5 s), any DoF. Measured (mujoco 3.17.0, sapien 3.0.3): 7.0e-6; 2.1e-5 tilted
# with a half-compensated leg; 3.9e-5 in the fluid. Without the term 0.049; the fluid's wrenches left out 0.56.
TOLERANCE = 1e-4


def _variant(tmp_path: Path, name: str, *edits: tuple[str, str]) -> Path:
    text = FIXTURE.read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / f"{name}.xml"
    path.write_text(text)
    return path


TILTED = (
    ('<body name="torso" pos="0 0 1">', '<body name="torso" pos="0 0 1" euler="20 30 10">'),
    ('axis="0 -1 0"', 'axis="0.3 -1 0.2"'),
    ('<body name="left" pos="0.2 0 0">', '<body name="left" pos="0.2 0 0" gravcomp="0.5">'),
)
FLUID = (('<option timestep="0.01"/>', '<option timestep="0.01" density="1.2" viscosity="0.2"/>'),)


def _worst_velocity(path: Path, mutate=None, euler: bool = False) -> float:
    result, model = contact_free(path, mutate)
    if euler:  # implicitfast treats fluid drag implicitly, which the loader does not
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    return float(paired_rollout(result, model, mujoco.MjData(model), 50).qvel.max())


def test_a_free_robot_kicked_by_its_joints_keeps_mujocos_root_velocity():
    assert _worst_velocity(FIXTURE) < TOLERANCE


def test_without_the_momentum_term_the_root_parts_from_mujoco():
    assert _worst_velocity(FIXTURE, lambda result: result.controller.without("momentum")) > 10 * TOLERANCE


def test_gravity_turning_a_partly_compensated_robot_is_carried(tmp_path):
    assert _worst_velocity(_variant(tmp_path, "tilted", *TILTED)) < TOLERANCE


class _Dropped(list):
    """The deliberate mistake: the fluid's wrenches never reach the momentum term."""

    def extend(self, items) -> None:
        pass


def _drop_fluid_wrenches(result) -> None:
    result.controller.edit("fluid").wrenches = _Dropped()


def test_drag_turning_a_robot_in_a_fluid_is_carried(tmp_path):
    path = _variant(tmp_path, "fluid", *TILTED[:2], *FLUID)
    assert _worst_velocity(path, euler=True) < TOLERANCE
    assert _worst_velocity(path, _drop_fluid_wrenches, euler=True) > 10 * TOLERANCE


# m/s or rad/s, the root's velocity after one step from a random state (joints far past their ends, fast) of the
# tilted robot. Measured (mujoco 3.17.0, sapien 3.0.3): 2e-7 to 9e-7 over seeds 0-2; the joints' part of the root
# rows left out 0.83; the half-compensated leg's lift left out 0.034.
ROOT_ROWS_TOLERANCE = 1e-5


def _root_after_one_step(path: Path, mutate=None) -> float:
    result, model = contact_free(path, mutate)
    qpos, qvel = random_state(model, np.random.default_rng(1))
    return float(one_step(result, model, qpos, qvel)[:6].max())


class _Uncoupled:
    """The deliberate mistake: MuJoCo's M u read as zero (`Passes.root_rows`), the joints' pull on the root left
    out."""

    def __getattr__(self, name: str):
        return getattr(mujoco, name)

    @staticmethod
    def mj_mulM(model, data, out, vector) -> None:
        out[:] = 0.0


def _unlifted(result) -> None:
    """The deliberate mistake: the compensated leg's lift left out of the root's forces."""
    term = result.controller.term("momentum")
    term.roots = [dataclasses.replace(root, lifted=()) for root in term.roots]


def test_the_root_rows_are_mujocos_step(tmp_path):
    assert _root_after_one_step(_variant(tmp_path, "tilted", *TILTED)) < ROOT_ROWS_TOLERANCE


def test_the_root_rows_take_the_joints_pull_and_the_lift(tmp_path, monkeypatch):
    path = _variant(tmp_path, "tilted", *TILTED)
    assert _root_after_one_step(path, _unlifted) > 10 * ROOT_ROWS_TOLERANCE
    monkeypatch.setattr(loader.runtime.centroidal, "mujoco", _Uncoupled())
    assert _root_after_one_step(path) > 10 * ROOT_ROWS_TOLERANCE


def test_reading_the_state_twice_changes_nothing():
    result, _ = contact_free(FIXTURE)
    for _ in range(3):
        result.set_ctrl(None)
        result.scene.step()
    first = result.get_state()
    second = result.get_state()
    assert np.array_equal(first[1], second[1])


def test_a_read_before_the_step_keeps_the_correction():
    result, model = contact_free(FIXTURE)
    data = mujoco.MjData(model)
    for _ in range(5):
        result.set_ctrl(None)
        result.get_state()  # between set_ctrl and the physics step
        mujoco.mj_step(model, data)
        result.scene.step()
    assert np.abs(result.get_state()[1] - data.qvel).max() < TOLERANCE


def _teleported_root_velocity(told: bool) -> np.ndarray:
    """set_ctrl, then the joints moved by hand in SAPIEN (not through `set_state`), then the physics step; `told`:
    the term is also told (`forget`) that no step starts where set_ctrl saw the state."""
    result, _ = contact_free(FIXTURE)
    for _ in range(3):
        result.set_ctrl(None)
        result.scene.step()
    result.set_ctrl(None)
    art = result.articulations[0]
    art.set_qpos(art.get_qpos() + np.float32(0.2))
    art.set_qvel(art.get_qvel() + np.float32(1.0))
    if told:
        result.controller.term("momentum").forget()
    result.scene.step()
    return result.get_state()[1][:6]


def test_a_step_from_joints_moved_by_hand_is_left_as_physx_ends_it():
    """The joints did not move by one step of their velocity from where set_ctrl saw them: the term cannot know
    the step's start, so it leaves PhysX's end state alone (as when told) instead of correcting from a stale one."""
    assert np.array_equal(_teleported_root_velocity(False), _teleported_root_velocity(True))


EDGE = Path(__file__).parents[1] / "corpus" / "fixtures" / "spinning_on_an_edge.xml"
# rad/s after 3 steps on the edge, against PhysX's own step (the term off). Measured (mujoco 3.17.0, sapien 3.0.3):
# 1.5e-4 (the dt (dA/dt) v part); 0.12 when the term ignores the contact and turns L back to its carried direction.
EDGE_TOLERANCE = 2e-3


def _spin_after_the_edge(off: bool = False) -> np.ndarray:
    """The root's spin after a contact turned it, where PhysX makes the contact (`contacts="physx"`)."""
    result, _, _ = at_keyframe(EDGE, contacts="physx")
    if off:
        result.controller.without("momentum")
    for _ in range(3):
        result.set_ctrl(None)
        result.scene.step()
    return result.get_state()[1][3:6]


def test_a_tree_a_contact_turns_keeps_physxs_angular_momentum(monkeypatch):
    physx = _spin_after_the_edge(off=True)
    assert np.abs(_spin_after_the_edge() - physx).max() < EDGE_TOLERANCE
    # the deliberate mistake: the term blind to the contact turns L back to its carried direction
    monkeypatch.setattr(loader.runtime.momentum, "touching", lambda links, contacts: False)
    assert np.abs(_spin_after_the_edge() - physx).max() > 10 * EDGE_TOLERANCE


def _momenta(term, qpos: np.ndarray, qvel: np.ndarray) -> tuple[list, list]:
    """Per root of `term`: the tree's momentum at (qpos, qvel) and the drift (dA/dt) qvel, from the term's passes."""
    from loader.runtime.centroidal import Ended

    (momenta,) = term.passes.momenta([Ended(qpos, qvel, qpos, qvel, np.zeros_like(qvel), [], [])])
    return momenta.started, momenta.drifts


def test_the_momentum_drift_is_the_derivative_of_a_v(tmp_path):
    """(dA/dt) v from MuJoCo's RNE at zero acceleration equals the forward difference (A(q + e v) - A(q)) v / e of
    the tilted, partly compensated robot's momentum at a random velocity (agreement 1e-5 of the largest term, the
    difference's own error). Mutation: the weight the root carries left in (the RNE's force at zero acceleration
    holds the tree up against gravity)."""
    from loader import MJCFLoader

    result = MJCFLoader().load(_variant(tmp_path, "tilted", *TILTED))
    term, model = result.controller.term("momentum"), result.model
    qpos, qvel = model.qpos0.copy(), np.random.default_rng(3).standard_normal(model.nv)

    def difference() -> np.ndarray:
        eps = 1e-7
        ahead = qpos.copy()
        mujoco.mj_integratePos(model, ahead, qvel, eps)
        return (np.array(_momenta(term, ahead, qvel)[0]) - np.array(_momenta(term, qpos, qvel)[0])) / eps

    expected = difference()
    drift = np.array(_momenta(term, qpos, qvel)[1])
    np.testing.assert_allclose(drift, expected, atol=1e-5 * np.abs(expected).max())
    term.passes.rates_weight = np.zeros_like(term.passes.rates_weight)
    assert np.abs(np.array(_momenta(term, qpos, qvel)[1]) - expected).max() > 1.0
