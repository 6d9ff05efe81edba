"""The opt-in `maniskill_tensor` tier (conformance/tiers/maniskill.py): `mujoco_ctrl_tensor` judged through
ManiSkill's `env.step`, with what the law does not carry and the harness can remove taken out of both sides, and
what stays named. Each check is shown to bite with a deliberate mistake."""

from __future__ import annotations

import importlib
import warnings

import pytest
from support.corpus import menagerie_root, suite_path

torch = pytest.importorskip("torch", reason="torch is not installed (the `maniskill` extra)")
pytest.importorskip("mani_skill", reason="mani_skill is not installed (the `maniskill` extra)")

from conformance import tolerances
from conformance.session import open_session
from conformance.tiers import TIERS

TIER = "maniskill_tensor"
TOL = tolerances.load()
tier_module = importlib.import_module("conformance.tiers.maniskill")


def _session(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return open_session(str(suite_path(name)))


def _judged(name: str):
    session = _session(name)
    return TIERS[TIER](session.result, session.model, 0, TOL)


def _judged_path(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = open_session(str(path))
    return TIERS[TIER](session.result, session.model, 0, TOL)


@pytest.mark.parametrize("mistake", [None, "hard_limits", "no_limit_rows"])
def test_the_law_carries_the_joint_limits(monkeypatch, mistake):
    """The hopper folds into its joint limits within the tier's run, which leaves them in on both sides: the law
    solves MuJoCo's soft limit rows, and the robot, built in the mode, holds no PhysX limit in their way. Each mistake
    fails it: the limits left to PhysX's hard ones (the plan without them), or PhysX's out of the way with no rows
    solved."""
    from loader.maniskill import agent, joint_actuation

    if mistake == "hard_limits":
        plan = agent.plan_joint_actuation

        def hard(*args, **kwargs):
            law = plan(*args, **kwargs)
            law.limits.limited[:] = False
            return law

        monkeypatch.setattr(agent, "plan_joint_actuation", hard)
    elif mistake == "no_limit_rows":
        monkeypatch.setattr(
            joint_actuation, "constraint_force", lambda law, matrix, q, v, smooth, *frames: torch.zeros_like(smooth)
        )
    report = _judged("hopper")
    assert report.status == ("pass" if mistake is None else "fail"), [(m.name, m.max) for m in report.metrics]
    assert not any("limits" in note for note in report.notes if "taken out" in note)


@pytest.mark.parametrize("mistake", [None, "no_frictionloss"])
def test_the_law_carries_frictionloss(monkeypatch, mistake):
    """go1's joints have frictionloss (0.2 N m), which the tier leaves in on both sides: the law solves MuJoCo's
    frictionloss rows and go1 passes. With the rows left out of the plan, it fails."""
    from loader.maniskill import agent

    root = menagerie_root()
    if root is None:
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    if mistake:
        plan = agent.plan_joint_actuation

        def frictionless(*args, **kwargs):
            law = plan(*args, **kwargs)
            law.friction.weight[:] = 0.0
            return law

        monkeypatch.setattr(agent, "plan_joint_actuation", frictionless)
    report = _judged_path(root / "unitree_go1/go1.xml")
    assert report.status == ("pass" if mistake is None else "fail"), [(m.name, m.max) for m in report.metrics]


@pytest.mark.parametrize("mistake", [None, "gain_off"])
def test_the_tier_catches_a_law_with_its_gains_two_percent_off(monkeypatch, mistake):
    """The cheetah's law passes; with every actuator's gain 2 % off in the plan the robot is registered with, the
    same tier fails."""
    from loader.maniskill import agent

    if mistake:
        plan = agent.plan_joint_actuation

        def off(*args, **kwargs):
            law = plan(*args, **kwargs)
            law.gain = law.gain * 1.02
            return law

        monkeypatch.setattr(agent, "plan_joint_actuation", off)
    assert _judged("cheetah").status == ("pass" if mistake is None else "fail")


@pytest.mark.parametrize("mistake", [None, "root_left_to_physx"])
def test_a_floating_robot_passes_with_mujocos_root(monkeypatch, mistake):
    """go1 passes the tier: after each physics step its floating root takes MuJoCo's step on the free joint's rows
    (loader/maniskill/free_root.py), and a read of the state settles the last one. Mutation: every step taken as
    pushed by a contact, so the root keeps PhysX's step, which conserves the tree's momentum where MuJoCo keeps qvel:
    the tier fails (its one-step root velocity)."""
    from loader.maniskill.joint_actuation import JointActuationController

    root = menagerie_root()
    if root is None:
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    if mistake:
        monkeypatch.setattr(JointActuationController, "touched", lambda self: self.ctrl.new_ones(1).bool())
    report = _judged_path(root / "unitree_go1/go1.xml")
    assert report.status == ("pass" if mistake is None else "fail"), [(m.name, m.max) for m in report.metrics]


@pytest.mark.parametrize("mistake", [None, "act_not_set"])
def test_each_sample_starts_the_law_at_mujocos_activations(tmp_path, monkeypatch, mistake):
    """The plan tests' chain with a filter, an integrator and an exact filter acting early (its fixed tendon
    actuator left out: its velocity cross terms are explicit in the law): each one-step sample sets MuJoCo's state,
    its activations among it, and the law starts from them, so the tier passes. Mutation: the law's activations left
    as the last sample ended them."""
    from test_joint_actuation import ACTUATED

    tendon = '<general tendon="t" gear="1.5" gainprm="3" biastype="affine" biasprm="0 -4 -1.5" forcerange="-2 2"/>'
    xml = ACTUATED.format(integrator="implicitfast")
    assert tendon in xml
    path = tmp_path / "activated_chain.xml"
    path.write_text(xml.replace(tendon, ""))
    if mistake:
        monkeypatch.setattr(tier_module.ThroughTensorEnv, "set_act", lambda self, act: self.result.set_act(act))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = open_session(str(path))
    assert session.model.na == 3
    report = TIERS[TIER](session.result, session.model, 0, TOL)
    assert report.status == ("pass" if mistake is None else "fail"), [(m.name, m.max) for m in report.metrics]
