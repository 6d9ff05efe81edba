"""PhysX's solver: its iterations from the coupling of an articulation's drives (loader/plan/solver_iterations.py),
and under TGS the drives written as joint forces (loader/runtime/drive_forces.py).

MuJoCo is the oracle: dm_control finger's two damped, motor-driven hinges couple strongly (Gauss-Seidel radius
0.49), and SAPIEN's default 10 position iterations leave its drives unconverged. Measured over 1 s of
sinusoidal ctrl, contact off, MuJoCo implicitfast: 4.0e-7 rad at the loader's 20, 2.2e-6 at 15, 6.4e-5 at 10.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, suite_path
from support.lockstep import contact_free, replay, solver_scene

from loader import MJCFLoader
from loader.plan import physx_settings
from loader.plan.solver_iterations import drive_radii, gauss_seidel_radius, sweeps_needed

ROLLOUT_TOLERANCE = 5e-6  # rad, measured 4.0e-7


def test_gauss_seidel_radius_of_a_two_by_two_system():
    # for [[a, c], [c, b]] Gauss-Seidel's iteration matrix has eigenvalues 0 and c^2 / (a b)
    a, b, c = 2.0, 3.0, 1.5
    assert np.isclose(gauss_seidel_radius(np.array([[a, c], [c, b]])), c * c / (a * b))
    assert gauss_seidel_radius(np.diag([1.0, 2.0, 3.0])) == 0.0
    assert sweeps_needed(0.5, residual=1e-6) == 20  # 0.5^20 = 9.5e-7


def _finger_ctrl(step, data):
    return 0.2 * np.array([np.sin(step * 0.2), np.cos(step * 0.1)])


def _finger(iterations):
    def mutate(result):
        if iterations is not None:
            for articulation in result.articulations:
                articulation.solver_position_iterations = iterations

    return contact_free(suite_path("finger"), mutate)


def test_finger_drives_converge_with_the_iterations_the_loader_picks():
    result, model = _finger(None)
    assert result.articulations[0].solver_position_iterations >= 20
    errors = replay(result, model, _finger_ctrl, 1.0)
    assert errors.max() < ROLLOUT_TOLERANCE, errors.max()


@pytest.mark.usefixtures("terms")
def test_sapiens_default_iterations_leave_the_finger_unconverged():
    """The mutation: the same replay at SAPIEN's 10 iterations fails the tolerance."""
    result, model = _finger(10)
    errors = replay(result, model, _finger_ctrl, 1.0)
    assert errors.max() > ROLLOUT_TOLERANCE, errors.max()


def test_iterations_are_never_lowered_and_can_be_kept_or_set():
    loose = MJCFLoader().load(suite_path("cartpole"))  # weak coupling: SAPIEN's default stays
    assert [a.solver_position_iterations for a in loose.articulations] == [10]
    keep = MJCFLoader()
    keep.solver_iterations = None
    assert all(a.solver_position_iterations == 10 for a in keep.load(suite_path("finger")).articulations)


TENDON_SERVO = """<mujoco><option integrator="{integrator}" timestep="0.002"/><worldbody><body>
  <joint name="a" axis="0 1 0" damping="0.01"/><geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".05"/>
  <body pos=".2 0 0"><joint name="b" axis="0 1 0" damping="0.01"/>
    <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".05"/></body></body></worldbody>
  <tendon><fixed name="t"><joint joint="a" coef="1"/><joint joint="b" coef="1"/></fixed></tendon>
  <actuator><velocity tendon="t" kv="{kv}"/></actuator></mujoco>"""


def _iterations(integrator: str, kv: float) -> int:
    spec = mujoco.MjSpec.from_string(TENDON_SERVO.format(integrator=integrator, kv=kv))
    return MJCFLoader().load(spec).articulations[0].solver_position_iterations


def test_a_tendon_servos_kv_couples_the_drives_only_where_the_integrator_makes_it_implicit():
    # under implicitfast the servo's kv diagonal rides on the two joints' drives (coupled through the chain's
    # inertia): more sweeps; under Euler kv is an explicit force and leaves the drive rows as they were
    assert _iterations("implicitfast", 5.0) > _iterations("implicitfast", 0.0)
    assert _iterations("Euler", 5.0) == _iterations("Euler", 0.0)


FOLDING_ARM = FIXTURES / "folding_servo_arm.xml"


def _arm_ctrl(step, data):
    return np.array([0.1, -2.618, 0.0]) + 0.3 * np.array(
        [np.sin(step * 0.02), np.cos(step * 0.03), np.sin(step * 0.05)]
    )


@pytest.mark.usefixtures("terms")
def test_the_iterations_cover_the_keyframes_where_the_drives_couple_more_than_at_qpos0():
    """Measured from the stretched keyframe over 1 s: 4.8e-7 rad at the keyframe's 41 sweeps, 4.0e-5 at qpos0's 16
    (the mutation: the rule at qpos0 alone)."""
    result, model = contact_free(FOLDING_ARM)
    weights = result.controller.drive_weights()
    at_qpos0 = sweeps_needed(drive_radii(model, weights, [], result.mapping)[0])
    at_key = sweeps_needed(drive_radii(model, weights, [], result.mapping, model.key_qpos[0])[0])
    assert at_key > at_qpos0
    assert result.articulations[0].solver_position_iterations == at_key
    assert replay(result, model, _arm_ctrl, 1.0).max() < ROLLOUT_TOLERANCE

    def qpos0_only(loaded):
        loaded.articulations[0].solver_position_iterations = at_qpos0

    result, model = contact_free(FOLDING_ARM, qpos0_only)
    assert replay(result, model, _arm_ctrl, 1.0).max() > ROLLOUT_TOLERANCE


def test_the_radii_run_on_one_blas_thread(monkeypatch):
    """The load's linear algebra (each tree's inverse inertia, the radii) runs on one BLAS thread whatever the
    process runs with, and back on its threads after: threaded, a humanoid's took a hundred times longer on busy
    shared cores for the same numbers."""
    from threadpoolctl import threadpool_info, threadpool_limits

    import loader.model.mj

    def blas_threads() -> set[int]:
        return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}

    seen = []
    pinv = np.linalg.pinv

    def recorded(*args, **kwargs):
        seen.append(blas_threads())
        return pinv(*args, **kwargs)

    monkeypatch.setattr(loader.model.mj.np.linalg, "pinv", recorded)
    with threadpool_limits(limits=2, user_api="blas"):
        MJCFLoader().load(suite_path("humanoid"))
        after = blas_threads()
    assert seen and all(threads == {1} for threads in seen), seen
    assert after == {2}


# PhysX's TGS solver: the drives written as joint forces (loader/runtime/drive_forces.py)

# rad, the largest |SAPIEN - MuJoCo| joint position over 0.5 s of a sine on every ctrl, contact off, SAPIEN on TGS:
# measured 2.3e-5 (folding_servo_arm from its keyframe), 5.5e-6 (humanoid), 6.0e-7 (cheetah) (mujoco 3.17.0,
# sapien 3.0.3); with TGS stepping the PhysX drives instead: 6.1e-3, 0.15, 9.2e-2
TGS_TOLERANCE = 1e-4


def _tgs_rollout(path) -> float:
    model = mujoco.MjModel.from_xml_path(str(path))
    loader = MJCFLoader().set_scene(solver_scene(model, tgs=True))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = loader.load(str(path))
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    rates = 2 * np.pi * model.opt.timestep * np.arange(1, model.nu + 1)
    base = model.key_ctrl[0].copy() if model.nkey else np.zeros(model.nu)
    return float(replay(result, model, lambda step, data: base + 0.5 * np.sin(rates * step), 0.5).max())


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("path", [FIXTURES / "folding_servo_arm.xml", suite_path("humanoid"), suite_path("cheetah")])
def test_under_tgs_the_drives_are_written_as_forces_and_follow_mujoco(path, monkeypatch):
    """Stiff position servos (folding_servo_arm), a floating humanoid's motors and joint springs and dampers: under
    TGS they follow MuJoCo as under PGS; with TGS stepping PhysX's drives they do not."""
    assert _tgs_rollout(path) < TGS_TOLERANCE
    monkeypatch.setattr(physx_settings, "uses_tgs", lambda scene: False)  # the drives left to TGS
    assert _tgs_rollout(path) > 10 * TGS_TOLERANCE


def test_a_force_limit_edited_into_a_law_holds_under_tgs():
    """A drive law's force limit holds where TGS has no drive to clamp: no joint force passes it, and it binds."""
    path = FIXTURES / "folding_servo_arm.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    result = MJCFLoader().set_scene(solver_scene(model, tgs=True)).load(str(path))
    limit = 30.0
    for law in result.controller.edit_laws().values():
        law.force_limit = limit
    result.reset(0)
    articulation, worst = result.articulations[0], 0.0
    for step in range(100):
        result.set_ctrl(model.key_ctrl[0] + 0.8 * np.sin(2 * np.pi * 0.002 * step * np.arange(1, model.nu + 1)))
        worst = max(worst, float(np.abs(articulation.get_qf()).max()))
        result.scene.step()
    assert worst == pytest.approx(limit, rel=1e-6)


def _tgs_states(share: bool) -> tuple[np.ndarray, int]:
    """Menagerie-free: folding_servo_arm under TGS for 200 steps with contacts on (so the rows solve every step);
    the final state, and the steps whose drives read the rows' forward pass (`share` False: none may)."""
    from loader.runtime.drive_forces import DriveForces
    from loader.runtime.rows import RowTerm

    path = FIXTURES / "folding_servo_arm.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    result = MJCFLoader().set_scene(solver_scene(model, tgs=True)).load(str(path))
    shared = 0
    rows, writer = result.controller.term("rows"), result.controller.term("drives")
    assert isinstance(rows, RowTerm) and isinstance(writer, DriveForces)
    contribute, dynamics = rows.contribute, writer.dynamics

    def rows_contribute(step):
        contribute(step)
        if not share:
            step.forwarded = None

    def counted(step):
        nonlocal shared
        shared += step.forwarded is not None
        return dynamics(step)

    rows.contribute, writer.dynamics = rows_contribute, counted
    result.reset(0)
    for step in range(200):
        result.set_ctrl(model.key_ctrl[0] + 0.8 * np.sin(2 * np.pi * 0.002 * step * np.arange(1, model.nu + 1)))
        result.scene.step()
    q, v = result.get_state()
    return np.concatenate([q, v]), shared


@pytest.mark.usefixtures("terms")
def test_under_tgs_the_drives_read_the_rows_forward_pass():
    """Where the rows ran MuJoCo's forward pass at the step's state, the drives read its M and bias instead of
    running MuJoCo's passes again: every step, and bit for bit what their own passes give."""
    own, none = _tgs_states(share=False)
    shared, steps = _tgs_states(share=True)
    assert none == 0 and steps == 200
    np.testing.assert_array_equal(shared, own)
