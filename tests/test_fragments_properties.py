"""The fragment properties under the CI profile (derandomized, bounded), seeded with the corner cases.

Each test also checks, through the tally, that the property really exercised what it claims: documents that
compiled and passed the tiers, documents MuJoCo rejected, actuators compared. Skips and excuses are logged."""

from __future__ import annotations

import logging
from types import SimpleNamespace

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
        '</worldbody><actuator><velocity joint="j" kv="1"/></actuator></mujoco>')
    reason = mujoco_ill_posed(model, 20)
    assert (reason == "MuJoCo itself is unstable on the model with its actuators on (bad qacc)") is unstable, reason


def test_a_failure_is_excused_as_the_limit_gap_only_when_mujoco_reached_a_limit():
    """The actuated run's own count of steps at a limit excuses its failure; without it, and with the zero-command
    run staying clear of the (wide) limits, the failure stands."""
    import mujoco

    from conformance.fragments.properties import limits_excuse
    from conformance.report import TierReport
    from conformance.tolerances import load
    from loader.errors import Unsupported

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><option gravity="0 0 0"/><worldbody><body><joint name="j" range="-90 90"/><geom size=".1"/></body>'
        '</worldbody></mujoco>')

    listed = SimpleNamespace(approximations=[Unsupported("joint", "limits", "PhysX joint limits are hard; "
                                                         "MuJoCo's are soft")], unsupported=[])

    def report(limit_steps: int) -> TierReport:
        return TierReport("actuated", "fail", [], [], settings={"limit_steps": limit_steps})

    assert limits_excuse(report(3), listed, model, load())
    assert not limits_excuse(report(0), listed, model, load())
    assert not limits_excuse(report(3), SimpleNamespace(approximations=[], unsupported=[]), model, load())
