"""A `Batch` drives copies of one model in their own scenes: each copy must come out of every step exactly as the
same copy driven by its own `set_ctrl`, and the array stages must really run once for all copies."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conformance.session import quiet_load
from loader import Batch, ControlError
from tests.support.corpus import FIXTURES, menagerie_root, mjcf_file, suite_path
from tests.support.lockstep import solver_scene

COPIES = 3
STEPS = 60

# Euler (kv explicit), a filtered actuator (activation per copy), a tendon actuator (a stage that runs per copy), a
# forcerange that binds under the larger commands (clamps per copy) and a floating root (momentum per copy).
MIXED = """
<mujoco>
  <option integrator="Euler" timestep="0.004"/>
  <worldbody>
    <body name="root" pos="0 0 1">
      <freejoint/>
      <geom type="box" size=".1 .08 .05" mass="2"/>
      <body name="a" pos=".1 0 0">
        <joint name="h1" axis="0 1 0" range="-1 1" damping=".05"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03" mass=".4"/>
        <body name="b" pos=".3 0 0">
          <joint name="h2" axis="0 1 0" stiffness="2" springref=".2"/>
          <geom type="capsule" fromto="0 0 0 .25 0 0" size=".025" mass=".3"/>
        </body>
      </body>
      <body name="c" pos="-.1 0 0">
        <joint name="h3" axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 -.25 0 0" size=".025" mass=".3"/>
      </body>
    </body>
  </worldbody>
  <tendon><fixed name="t"><joint joint="h2" coef="1"/><joint joint="h3" coef="-.5"/></fixed></tendon>
  <actuator>
    <position joint="h1" kp="30" kv="2" forcerange="-3 3"/>
    <general joint="h2" dyntype="filter" dynprm=".05" gainprm="4" ctrlrange="-1 1"/>
    <motor tendon="t" gear="2" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""
# Only array stages under Euler: the servo's kv leaves the drive as an explicit force, once for every copy.
SERVO = MIXED.replace('<motor tendon="t" gear="2" ctrlrange="-1 1"/>', "").replace('forcerange="-3 3"', "")


def copies(path, count: int) -> list:
    """`count` loads of `path`, each in a scene of its own."""
    results = [quiet_load(path) for _ in range(count)]
    assert len({id(result.scene) for result in results}) == count
    return results


def model_paths() -> list:
    root = menagerie_root()
    panda = root / "franka_emika_panda/panda.xml" if root else None
    marks = [] if root else [pytest.mark.skip(reason="Menagerie slice not installed (extra 'menagerie')")]
    every = {"actuators", "stiffness", "drives"}
    return [  # with the stages that must have run once for every copy at some step
        pytest.param(suite_path("humanoid"), every, id="suite/humanoid"),
        pytest.param(suite_path("cheetah"), every, id="suite/cheetah"),
        pytest.param(panda, set(), id="menagerie/panda", marks=marks),  # its forceranges bind under the walk
        pytest.param(MIXED, set(), id="mixed"),
        pytest.param(SERVO, every, id="euler_servo"),
    ]


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize(("path", "stages"), model_paths())
def test_a_batch_steps_each_copy_as_its_own_set_ctrl(path, stages, tmp_path):
    path = mjcf_file(tmp_path, path) if isinstance(path, str) else path
    batch_results, lone = copies(path, COPIES), copies(path, COPIES)
    batch = Batch(batch_results)
    model = lone[0].model
    rng = np.random.default_rng(7)
    for a, b in zip(batch_results, lone):  # each pair from a start of its own
        qpos, _ = a.get_state()
        qvel = 0.1 * rng.standard_normal(model.nv)
        a.set_state(qpos, qvel)
        b.set_state(qpos, qvel)
    low = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 0], -1.0)
    high = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 1], 1.0)
    batched = set()
    for _ in range(STEPS):
        ctrl = rng.uniform(low, high, size=(COPIES, model.nu)) * 1.5  # past ctrlrange now and then: clamped
        batch.step(ctrl)
        batched |= set(batch.batched)
        for k, result in enumerate(lone):
            result.set_ctrl(ctrl[k])
            result.scene.step()
    for a, b in zip(batch_results, lone):
        qa, va = a.get_state()
        qb, vb = b.get_state()
        np.testing.assert_array_equal(qa, qb)
        np.testing.assert_array_equal(va, vb)
        for art_a, art_b in zip(a.articulations, b.articulations):
            np.testing.assert_array_equal(art_a.get_qf(), art_b.get_qf())
            targets_a = [j.drive_target for j in art_a.active_joints]
            targets_b = [j.drive_target for j in art_b.active_joints]
            np.testing.assert_array_equal(np.array(targets_a), np.array(targets_b))
    assert stages <= batched
    if batch_results[0].controller.term("momentum") is not None:  # the roots settled on the stack of copies
        assert batch.passes


def _tgs_copies(path, count: int) -> list:
    """`count` loads of `path` under PhysX's TGS solver, each in a scene of its own."""
    import mujoco

    from loader import MJCFLoader

    model = mujoco.MjModel.from_xml_path(str(path))
    return [MJCFLoader().set_scene(solver_scene(model, tgs=True)).load(str(path)) for _ in range(count)]


def _tgs_batch_against_lone_copies() -> float:
    """The largest joint position difference between suite cheetah's batched copies and lone ones after 40 steps
    under TGS."""
    path = suite_path("cheetah")
    batch_results, lone = _tgs_copies(path, 2), _tgs_copies(path, 2)
    batch, rng = Batch(batch_results), np.random.default_rng(0)
    nu = lone[0].model.nu
    for _ in range(40):
        ctrl = rng.uniform(-0.3, 0.3, (2, nu))
        batch.step(ctrl)
        for k, result in enumerate(lone):
            result.set_ctrl(ctrl[k])
            result.scene.step()
    return max(float(np.abs(a.get_state()[0] - b.get_state()[0]).max()) for a, b in zip(batch_results, lone))


@pytest.mark.usefixtures("terms")
def test_a_batch_under_tgs_steps_each_copy_as_its_own_set_ctrl(monkeypatch):
    """Under TGS each copy's drive law is a joint force solved with its own M (`DriveForces`), never PhysX drive
    targets written for every copy at once. Mutation: the drive writer's batch stage (targets) under TGS, which TGS
    steps its own way (0.019 rad apart after 40 steps)."""
    from loader.runtime.drive_forces import DriveForces
    from loader.runtime.drive_writer import DriveWriter

    assert _tgs_batch_against_lone_copies() == 0.0
    monkeypatch.setattr(DriveForces, "batch", DriveWriter.batch)
    assert _tgs_batch_against_lone_copies() > 1e-3


def test_a_batch_of_copies_on_mujocos_own_step_steps_each_as_its_own_set_ctrl():
    """Copies whose joint forces come from MuJoCo's own step (`use_mujoco_step`) step in a batch exactly as alone.
    Mutation: the batch running the terms' stages on them instead (1.0e-7 rad apart after 60 steps)."""
    path = FIXTURES / "folding_servo_arm.xml"
    batch_results, lone = copies(path, COPIES), copies(path, COPIES)
    for result in (*batch_results, *lone):
        assert result.controller.use_mujoco_step() is None
    batch, model, rng = Batch(batch_results), lone[0].model, np.random.default_rng(3)
    for _ in range(STEPS):
        ctrl = rng.uniform(-1.0, 1.0, size=(COPIES, model.nu))
        batch.step(ctrl)
        for k, result in enumerate(lone):
            result.set_ctrl(ctrl[k])
            result.scene.step()
    for a, b in zip(batch_results, lone):
        np.testing.assert_array_equal(a.get_state()[0], b.get_state()[0])
    assert batch.batched == []


def test_a_batch_refuses_a_command_per_copy_of_the_wrong_shape(tmp_path):
    batch = Batch(copies(mjcf_file(tmp_path, MIXED), 2))
    with pytest.raises(ControlError, match=r"shape \(3,\)"):
        batch.set_ctrl(np.zeros(3))
    with pytest.raises(ControlError, match=r"ctrl\[1\]\[0\] is nan"):
        batch.set_ctrl(np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]))


def test_a_batch_holds_copies_of_one_model_only(tmp_path):
    other = mjcf_file(tmp_path, MIXED.replace('<motor tendon="t" gear="2" ctrlrange="-1 1"/>', ""), "other.xml")
    with pytest.raises(ValueError, match="not a copy"):
        Batch([*copies(mjcf_file(tmp_path, MIXED), 1), *copies(other, 1)])


def test_a_copy_edited_apart_is_stepped_by_its_own_laws(tmp_path):
    """A copy whose laws were edited after the batch was made no longer shares the first copy's: every stage runs
    per copy, and the edited copy steps as a lone copy with the same edit. Mutation: the stages batched anyway."""
    path = mjcf_file(tmp_path, SERVO)
    batch_results, lone = copies(path, 2), copies(path, 2)
    batch = Batch(batch_results)
    for results in (batch_results, lone):
        law = next(iter(results[1].controller.edit_laws().values()))
        law.stiffness += 5.0
    ctrl = np.full((2, lone[0].model.nu), 0.3)
    for _ in range(20):
        batch.step(ctrl)
        for k, result in enumerate(lone):
            result.set_ctrl(ctrl[k])
            result.scene.step()
    assert batch.batched == []
    for a, b in zip(batch_results, lone):
        np.testing.assert_array_equal(a.get_state()[0], b.get_state()[0])


def _stack_and_its_numbers(path, mistake: str = "") -> tuple[bool, float]:
    """The stack of COPIES copies of a model's trees: whether `stack` found it exact, and the largest difference
    between each copy's momenta and root rows from the stack's passes and from its own model's, at random states.
    `mistake`: one body of the last copy 1e-12 kg heavier in the stack ("mass"), or its first root DoF's armature
    1e-12 larger ("armature": only the root rows read M)."""
    from loader.runtime.centroidal import Ended, Passes, gives_each_copy_its_own, random_state, stack

    term = quiet_load(path).controller.term("momentum")
    model = term.model
    stacked = stack(model, COPIES)
    assert stacked is not None
    if mistake == "mass":
        stacked.body_mass[-1] += 1e-12
    elif mistake == "armature":
        stacked.dof_armature[(COPIES - 1) * model.nv + term.roots[0].dofadr] += 1e-12
    exact = gives_each_copy_its_own(model, stacked, COPIES)
    rng = np.random.default_rng(11)
    ended, balanced = [], [root for root in term.roots if root.balanced]
    for _ in range(COPIES):
        (qpos0, qvel0), (qpos1, qvel1) = random_state(model, rng), random_state(model, rng)
        ended.append(Ended(qpos0, qvel0, qpos1, qvel1, rng.standard_normal(model.nv), [], [], balanced))
    stacked_passes = Passes(stacked, model, term.roots, np.array(term.gravity), COPIES)
    together = stacked_passes.momenta(ended)
    alone = Passes(model, model, term.roots, np.array(term.gravity))
    rows = [dataclasses.replace(one, qvel1=one.qvel1.copy()) for one in ended]
    stacked_passes.root_rows(rows, [[]] * COPIES, 0.01)
    worst = 0.0
    for one, joint in zip(ended, rows):
        own = dataclasses.replace(one, qvel1=one.qvel1.copy())
        alone.root_rows([own], [[]], 0.01)
        worst = max(worst, float(np.abs(own.qvel1 - joint.qvel1).max()))
    for one, joint in zip(ended, together):
        (own,) = alone.momenta([one])
        for name in ("kept", "started", "joints_part", "drifts"):
            worst = max(worst, float(np.abs(np.array(getattr(own, name)) - np.array(getattr(joint, name))).max()))
        for a, b in zip(own.starts, joint.starts):
            worst = max(
                worst,
                float(
                    np.abs(
                        np.array([*a.centre, a.mass, *a.inertia, *a.moment])
                        - [*b.centre, b.mass, *b.inertia, *b.moment]
                    ).max()
                ),
            )
    return exact, worst


@pytest.mark.parametrize("path", [suite_path("humanoid"), MIXED], ids=["suite/humanoid", "mixed"])
def test_a_stack_of_copies_gives_each_copy_its_own_numbers(path, tmp_path):
    """A `Batch` runs the momentum's MuJoCo passes once for every copy, on one model holding all their trees: each
    copy's momenta, trees and root rows come out exactly as from its own model, at random states. Mutations: one
    body of the last copy 1e-12 kg heavier in the stack, or one DoF's armature, which `stack`'s own check refuses
    and the numbers show."""
    path = mjcf_file(tmp_path, path) if isinstance(path, str) else path
    assert _stack_and_its_numbers(path) == (True, 0.0)
    for mistake in ("mass", "armature"):
        exact, worst = _stack_and_its_numbers(path, mistake)
        assert not exact and worst > 0.0, mistake
