"""Every tolerance is backed by a mutation: a small deliberate mistake in the built SAPIEN scene must make
the tier meant to catch it fail, while the untouched scene passes the same tier."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import sapien

from conformance import loaders, sapien_side, tolerances
from conformance.corpus import dm_control_suite_dir
from conformance.session import open_session
from conformance.tiers import TIERS

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "corpus" / "fixtures" / "pendulum.xml"
TOL = tolerances.load()


def _path(name: str) -> Path:
    if name == "fixture_pendulum":
        return FIXTURE
    suite = dm_control_suite_dir()
    if suite is None:
        pytest.skip("dm_control is not installed")
    return suite / f"{name}.xml"


def _session(name: str, terms: bool = False):
    """The model's harness session, its joint forces from the loader's default law or, `terms`, the per-step
    terms."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return (loaders.terms if terms else open_session)(str(_path(name)))


def _tier(session, tier: str):
    return TIERS[tier](session.result, session.model, 0, TOL)


def _heaviest_body_link(session):
    model = session.model
    body = max(range(1, model.nbody), key=lambda b: model.body_mass[b])
    entry = session.result.mapping.bodies[body]
    return session.result.articulations[entry.articulation].links[entry.link]


def _last_hinge(session):
    """The SAPIEN joint of the last hinge (the lightest end of the chain)."""
    model = session.model
    hinges = [j for j, e in enumerate(session.result.mapping.joints) if e.kind == "hinge"]
    entry = session.result.mapping.joints[hinges[-1]]
    return session.result.articulations[entry.articulation].active_joints[entry.dofs[0]], model


def mutate_mass(session) -> None:
    link = _heaviest_body_link(session)
    link.mass = link.mass * 1.01


def mutate_joint_frame(session) -> None:
    joint, _ = _last_hinge(session)
    pose = joint.pose_in_child
    joint.pose_in_child = sapien.Pose(np.asarray(pose.p) + np.array([0.0, 0.001, 0.0]), pose.q)  # 1 mm, off-axis


def mutate_armature(session) -> None:
    joint, _ = _last_hinge(session)
    joint.armature = np.asarray(joint.armature) + 0.001


def mutate_collision_groups(session) -> None:
    for art in session.result.articulations:
        for link in art.links:
            for shape in link.collision_shapes:
                g = list(shape.get_collision_groups())
                if g[0] != g[1]:
                    shape.set_collision_groups([g[1], g[0], g[2], g[3]])
                    return
    raise AssertionError("no shape with contype != conaffinity to swap")


def mutate_joint_limit(session) -> None:
    # PhysX ignores a switch to +-inf (a change of joint motion) once the articulation is in a scene,
    # so the limit is dropped by widening it far past any motion, and with it the soft limit rows the loader
    # drives (loader/runtime/rows.py).
    session.result.controller.without("rows")  # PhysX's hard limit back, then widened below
    for a, art in enumerate(session.result.articulations):
        for d, joint in enumerate(art.active_joints):
            lo, hi = np.asarray(joint.limit)[0]
            if np.isfinite(lo) and np.isfinite(hi):
                joint.limit = [[-1e4, 1e4]]
                assert np.asarray(joint.limit)[0, 1] == 1e4
                return
    raise AssertionError("no limited joint to drop")


def mutate_timestep(session) -> None:
    session.result.scene.timestep = session.result.scene.timestep * 1.01


CASES = [
    # (mutation, tier, failing metric, models)
    (mutate_mass, "inertia", "mass", ["fixture_pendulum", "cartpole", "walker", "humanoid"]),
    (mutate_joint_frame, "kinematics", "position", ["fixture_pendulum", "reacher", "walker", "humanoid"]),
    (mutate_armature, "dynamics", None, ["fixture_pendulum", "acrobot", "reacher", "walker"]),
    (mutate_collision_groups, "collision", "groups", ["fixture_pendulum"]),
    (mutate_joint_limit, "structure", "limit", ["fixture_pendulum", "walker", "cheetah"]),
    (mutate_timestep, "dynamics", "settings_mismatches", ["fixture_pendulum"]),
]


@pytest.mark.parametrize(
    "mutation,tier,metric_name,model",
    [pytest.param(m, t, n, model, id=f"{m.__name__}-{model}") for m, t, n, models in CASES for model in models],
)
def test_mutation_is_caught(mutation, tier, metric_name, model):
    clean = _tier(_session(model), tier)
    assert clean.status == "pass", f"{model} {tier} must pass before the mutation: {clean.to_dict()}"
    session = _session(model)
    mutation(session)
    report = _tier(session, tier)
    assert report.status == "fail", f"{mutation.__name__} went unnoticed by {tier} on {model}"
    failed = {m.name for m in report.metrics if not m.passed}
    if metric_name is not None:
        assert metric_name in failed, failed


def test_one_percent_mass_error_is_measured_as_one_percent():
    session = _session("fixture_pendulum")
    mutate_mass(session)
    mass = next(m for m in _tier(session, "inertia").metrics if m.name == "mass")
    assert mass.max == pytest.approx(0.01, rel=1e-4)


def test_one_millimetre_frame_offset_is_measured_as_one_millimetre():
    session = _session("fixture_pendulum")
    mutate_joint_frame(session)
    position = next(m for m in _tier(session, "kinematics").metrics if m.name == "position")
    assert position.max == pytest.approx(0.001, rel=1e-3)


TINY_BODIES = """<mujoco><worldbody><body name="arm" pos="0 0 1"><joint name="hinge" axis="0 1 0"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
  <body name="dummy" pos=".3 0 0"><joint name="spin" axis="1 0 0"/>
    <inertial pos="0 0 0" mass="1e-9" diaginertia="3.3e-13 3.3e-13 6.1e-13"/></body>
  <body name="sensor" pos=".1 0 0"><inertial pos="0 0 0" mass=".05" diaginertia="0 0 0"/></body>
</body></worldbody></mujoco>"""


def _tiny_session(tmp_path):
    path = tmp_path / "tiny.xml"
    path.write_text(TINY_BODIES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return open_session(str(path))


def test_tiny_and_zero_moments_pass_on_the_absolute_floor_and_a_zero_one_is_listed(tmp_path):
    """A 1e-9 kg dummy link with 3e-13 kg m^2 moments is kept as it is; a welded sensor body with mass and a zero
    tensor gets the floor's stand-in, listed. Both pass the inertia tier (without the floor: relative error 1e300)."""
    session = _tiny_session(tmp_path)
    assert _tier(session, "inertia").status == "pass"
    assert any(e.kind == "body" and e.name == "sensor" for e in session.result.approximations)
    dummy = session.result.articulations[0].links[session.result.mapping.bodies[2].link]
    np.testing.assert_allclose(dummy.inertia, [3.3e-13, 3.3e-13, 6.1e-13], rtol=1e-6)


def test_a_tiny_tensor_wrong_by_more_than_the_floor_is_caught(tmp_path):
    """The deliberate mistake: the dummy link's moments 1e-9 kg m^2 (the floor is 1e-12)."""
    session = _tiny_session(tmp_path)
    dummy = session.result.articulations[0].links[session.result.mapping.bodies[2].link]
    dummy.inertia = np.full(3, 1e-9, np.float32)
    report = _tier(session, "inertia")
    assert report.status == "fail" and not next(m for m in report.metrics if m.name == "tensor").passed


def test_the_maniskill_tier_catches_a_robot_built_there_without_armature(monkeypatch):
    """The `maniskill` tier drives ManiSkill's own copy of the robot: a mistake in the ManiSkill build (the
    armature dropped) fails it while the same tier passes on the untouched build."""
    pytest.importorskip("mani_skill", reason="mani_skill is not installed (the `maniskill` extra)")
    from support.corpus import menagerie_root

    from loader.plan import physx_settings

    root = menagerie_root()
    if root is None or not (root / "franka_emika_panda/panda.xml").is_file():
        pytest.skip("Menagerie slice not installed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = open_session(str(root / "franka_emika_panda/panda.xml"))
    assert _tier(session, "maniskill").status == "pass"
    settings = physx_settings.apply_articulation_settings

    def without_armature(articulation, plans, timestep):
        settings(articulation, plans, timestep)
        for joint in articulation.active_joints:
            joint.set_armature(np.zeros(1, np.float32))

    monkeypatch.setattr(physx_settings, "apply_articulation_settings", without_armature)
    assert _tier(session, "maniskill").status in ("fail", "diverged")


def test_a_run_after_another_starts_with_no_link_force_left(monkeypatch):
    """Under the per-step terms the swimmer's fluid drag is a link force, which PhysX keeps until the next step
    (MuJoCo's own step, the default, gives it as joint forces). The dynamics tier's rollouts follow its one-step
    pass, whose last call only clears the command: they pass. Mutation: that call begins a physics step
    (`advance=True`), so its drag waits in PhysX and doubles the rollout's first."""
    assert _tier(_session("swimmer", terms=True), "dynamics").status == "pass"
    monkeypatch.setattr(
        sapien_side, "clear_command", lambda result, nv: result.set_ctrl(None, qfrc_applied=np.zeros(nv))
    )
    assert _tier(_session("swimmer", terms=True), "dynamics").status == "fail"


PAIRED = """<mujoco><worldbody><geom name="floor" type="plane" size="2 2 .1"/>
  <body name="ball" pos="0 0 .3"><freejoint/><geom name="ball" size=".1" contype="0" conaffinity="0"/></body>
  <body name="box" pos=".5 0 .3"><freejoint/><geom name="box" type="box" size=".1 .1 .1"/></body></worldbody>
  <contact><pair geom1="floor" geom2="ball"/></contact></mujoco>"""


def _paired_session(path: Path, geom: str | None = None, bit: int = 0):
    """The fixture's session, `bit` added to the g0 word of `geom`'s shape."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = open_session(str(path))
    if geom is not None:
        _, shape = sapien_side.geom_component(session.result, session.model.geom(geom).id)
        g = list(shape.get_collision_groups())
        shape.set_collision_groups([g[0] | bit, g[1], g[2], g[3]])
    return session


@pytest.mark.parametrize("geom,bit", [("ball", 1), ("box", 1 << 20)], ids=["used-bit-on-paired", "spare-on-unpaired"])
def test_the_collision_tier_allows_a_paired_geom_spare_bits_only(tmp_path, geom, bit):
    """The ball collides only through its pair, on a bit no contype or conaffinity uses: the tier passes. A used
    bit (contype's bit 0) added to the paired ball, or a spare bit added to the unpaired box, fails it."""
    path = tmp_path / "paired.xml"
    path.write_text(PAIRED)
    assert _tier(_paired_session(path), "collision").status == "pass"
    report = _tier(_paired_session(path, geom, bit), "collision")
    assert report.status == "fail" and "groups" in {m.name for m in report.metrics if not m.passed}
