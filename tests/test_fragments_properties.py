"""The fragment properties under the CI profile (derandomized, bounded), seeded with the corner cases.

Each test also checks, through the tally, that the property really exercised what it claims: documents that
compiled and passed the tiers, documents MuJoCo rejected, actuators compared. Skips and excuses are logged."""

from __future__ import annotations

import logging

import pytest

from conformance.fragments import Tally
from conformance.fragments.fuzz import CI_EXAMPLES, ci_settings, hypothesis_test

log = logging.getLogger(__name__)


def _run(name: str) -> dict[str, int]:
    tally = Tally()
    hypothesis_test(name, ci_settings(CI_EXAMPLES[name]), tally=tally)()
    delta = {key: count for key, count in tally.items() if count}
    log.info("%s property: %s", name, ", ".join(f"{k}: {v}" for k, v in sorted(delta.items())))
    return delta


@pytest.fixture(autouse=True)
def _no_regression_files(monkeypatch):
    # a failure here is reported with its document; saving to the corpus is the fuzz session's job
    monkeypatch.setenv("FRAGMENTS_SAVE_REGRESSIONS", "0")


def test_generated_documents_conform_to_mujoco():
    delta = _run("conformance")
    assert delta.get("compiled by MuJoCo", 0) >= 40, delta
    assert delta.get("rejected by MuJoCo", 0) >= 10, delta  # error parity on what the generator gets wrong
    for tier in ("structure", "kinematics", "inertia", "collision", "dynamics"):
        assert delta.get(f"tier {tier} pass", 0) >= 20, (tier, delta)
    assert delta.get("tier actuated pass", 0) >= 5, delta  # the same ctrl on both sides
    assert delta.get("actuators checked", 0) >= 10, delta
    assert delta.get("drive gains checked (dofs)", 0) >= 50, delta


def test_rejected_documents_raise_the_loaders_typed_error():
    delta = _run("error_parity")
    assert delta.get("rejected by MuJoCo", 0) >= CI_EXAMPLES["error_parity"] * 0.9, delta


def test_random_orientations_agree_on_forward_kinematics():
    delta = _run("kinematics")
    assert delta.get("tier kinematics pass", 0) >= CI_EXAMPLES["kinematics"] * 0.5, delta


@pytest.mark.parametrize("integrator, unstable", [("Euler", True), ("implicitfast", False)])
def test_a_model_that_blows_up_only_with_its_actuators_on_is_no_reference(integrator, unstable):
    """kv 1 on a 2 cm sphere: explicit under Euler, MuJoCo diverges within the stability run (it would pass the
    20 judged steps and fail them on the loader); implicit under implicitfast it is a reference."""
    import mujoco

    from conformance.fragments.properties import mujoco_ill_posed

    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><option integrator="{integrator}"/><worldbody><body><joint name="j"/><geom size="0.02"/></body>'
        '</worldbody><actuator><velocity joint="j" kv="1"/></actuator></mujoco>'
    )
    reason = mujoco_ill_posed(model, 20)
    assert (reason is not None and reason.startswith("MuJoCo itself is unstable on the model")) is unstable, reason


def _slide(option: str, joint: str, actuator: str):
    """A 1 kg slide at dt 0.01 (`option`, `joint`: extra attributes; `actuator`: its actuators), at rest after
    mj_forward: (model, data)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="0.01"{option}/><worldbody><body><joint name="s" type="slide"{joint}/>'
        f'<geom size="0.05" mass="1"/></body></worldbody><actuator>{actuator}</actuator></mujoco>'
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


@pytest.mark.parametrize("factor, unstable", [(3.8, False), (4.2, True)])
def test_an_explicit_servo_stiffness_past_the_step_s_region_is_no_reference(factor, unstable):
    """A position servo's kp on a 1 kg slide at dt 0.01 under implicitfast (which takes kv implicitly, kp not):
    dt^2 kp / m past 4 makes MuJoCo's own step ring up (on a robot whose inertia changes with its pose, slowly
    enough to pass its stability run). The oracle is MuJoCo's run, not the formula: its swing grows only past 4."""
    import mujoco

    from conformance.fragments.properties import explicit_stiffness_unstable

    model, data = _slide(' integrator="implicitfast"', "", f'<position joint="s" kp="{factor * 1e4}"/>')
    assert (explicit_stiffness_unstable(model, data, actuated=True) is not None) is unstable
    assert explicit_stiffness_unstable(model, data, actuated=False) is None  # no spring on the joint itself
    data.qpos[0] = 0.01
    swing = 0.0
    for _ in range(200):
        mujoco.mj_step(model, data)
        swing = max(swing, abs(float(data.qpos[0])))
    assert (swing > 0.1) is unstable, swing  # 0.046 at 3.8 (the step's ellipse, not growth), 3e5 at 4.2


@pytest.mark.parametrize("factor, unstable", [(3.8, False), (4.2, True)])
def test_a_joint_spring_past_the_step_s_region_makes_the_passive_run_no_reference(factor, unstable):
    """The same region for a joint's own spring (a fuzz find: a 2 cm sphere on a 5.5 N m/rad hinge spring, 4.1),
    judged before the stability run, which a slow ring-up outlasts."""
    from conformance.fragments.properties import mujoco_ill_posed

    model, _ = _slide("", f' stiffness="{factor * 1e4}"', "")
    reason = mujoco_ill_posed(model, 5)  # five steps: too few for the ring-up to blow up
    assert (reason is not None and "explicit stiffness" not in reason and "unstable" in reason) is unstable, reason


@pytest.mark.parametrize("factor, unstable", [(1.9, False), (2.1, True)])
def test_an_explicit_servo_damping_past_eulers_region_is_no_reference(factor, unstable):
    """A position servo's kv on a 1 kg slide at dt 0.01: Euler integrates it explicitly, and dt kv / m past 2
    grows the slide's speed every step, which MuJoCo flags only at 1e10 (a fuzz find: 27 on a light hinge)."""
    from conformance.fragments.properties import explicit_damping_unstable

    model, data = _slide("", "", f'<position joint="s" kp="1" kv="{factor * 100}"/>')
    assert (explicit_damping_unstable(model, data) is not None) is unstable


def test_the_robot_classes_generator_runs_clean_and_exercises_its_classes():
    """Past-the-end starts, URDF-style frictionloss, many limits at once, tiny and zero inertias, coupled fingers:
    every tier passes, the dynamic ones on most documents (the rest: MuJoCo unstable with its actuators on, or a
    joint-space inertia the loader lists as beyond float32)."""
    delta = _run("robot_classes")
    compiled = delta.get("compiled by MuJoCo", 0)
    assert compiled >= 50 and delta.get("rejected by MuJoCo", 0) == 0, delta
    assert delta.get("tier dynamics pass", 0) >= 0.7 * compiled, delta
    assert delta.get("tier actuated pass", 0) >= 0.4 * compiled, delta


def test_a_loader_that_keeps_the_hard_limit_on_frictional_joints_is_caught(monkeypatch):
    """The deliberate mistake, as the loader once was: a joint with frictionloss keeps PhysX's hard limit at
    MuJoCo's range and gets no soft limit row, so a joint started past its end is snapped back."""
    from hypothesis import given, settings

    import loader.runtime.controller
    from conformance.fragments.fuzz import robot_classes_property
    from conformance.fragments.robot_classes import robot_classes

    plan = loader.runtime.controller.plan_rows

    def hard_on_frictional(model, mapping, *args):
        term = plan(model, mapping, *args)
        if term is not None:
            frictional = {
                (t.articulation, t.dofs[0])
                for j, t in enumerate(mapping.joints)
                if t.kind in ("hinge", "slide") and model.dof_frictionloss[model.jnt_dofadr[j]] > 0
            }
            term.set_limits([limit for limit in term.limits if limit.key not in frictional])
            for j, t in enumerate(mapping.joints):
                if (t.articulation, (t.dofs or [None])[0]) in frictional:
                    term.mirror.jnt_limited[j] = 0
        return term

    monkeypatch.setattr(loader.runtime.controller, "plan_rows", hard_on_frictional)
    found = []

    @settings(ci_settings(40))
    @given(robot_classes())
    def caught(document):
        try:
            robot_classes_property(document, Tally())
        except AssertionError as error:
            found.append(str(error).splitlines()[0])

    caught()
    assert any(line.startswith(("dynamics tier", "actuated tier")) for line in found), found


def test_checked_documents_leave_no_files_and_never_share_a_name():
    """Documents are written into one scratch folder per process: each under a name of its own (MuJoCo caches
    meshes by file name), and its files are gone once it is checked."""
    from conformance.fragments import Body, Document, Element, MeshAsset, check_document
    from conformance.fragments.properties import _scratch
    from conformance.fragments.strategies import TETRA_FACES

    def tetra(size: float) -> Document:
        mesh = MeshAsset("m", [(0, 0, 0), (size, 0, 0), (0, size, 0), (0, 0, size)], TETRA_FACES)
        body = Body(
            "body",
            {"name": "b"},
            [Element("joint", {"name": "j"}), Element("geom", {"name": "g", "type": "mesh", "mesh": "m"})],
        )
        return Document(meshes=[mesh], bodies=[body])

    paths = []
    for size in (0.1, 0.3):
        outcome = check_document(tetra(size))
        assert outcome.compiled and not outcome.failures, outcome.failures
        assert not outcome.path.exists()
        paths.append(outcome.path)
    folder, _ = _scratch()
    assert paths[0].parent == paths[1].parent == folder and paths[0] != paths[1]
    assert list(folder.iterdir()) == []
