"""`run --loader physx` (conformance/physx_loader.py): this project's build with PhysX alone, servos as drives whose
damping is less K dt (`Servo.physx_damping`), judged by the `actuated` tier like the loader with its per-step terms.
MuJoCo is the oracle: stiff position servos step as MuJoCo's; what only `set_ctrl` carries (frictionloss) is lost."""

from __future__ import annotations

from support.corpus import FIXTURES

from conformance import tolerances
from conformance.loaders import open_with
from conformance.tiers.actuated import actuated
from loader import servos

TOL = tolerances.load()
ARM = FIXTURES / "folding_servo_arm.xml"


def _actuated(path):
    session = open_with("physx", str(path))
    report = actuated(session.result, session.model, 0, TOL)
    return report, {metric.name: metric.max for metric in report.metrics}


def test_position_servos_alone_step_as_mujocos():
    report, worst = _actuated(ARM)
    assert report.status == "pass", worst


def test_without_the_damping_correction_the_servos_do_not(monkeypatch):
    monkeypatch.setattr(servos.Servo, "physx_damping", lambda servo, timestep: list(servo.damping))
    report, worst = _actuated(ARM)
    assert report.status == "fail" and worst["one_step_qvel"] > 100 * TOL["actuated.one_step_qvel_fixed"]


def test_frictionloss_is_what_physx_alone_loses(tmp_path):
    text = ARM.read_text().replace(
        '<joint name="elbow" axis="0 1 0" damping="0.1"/>',
        '<joint name="elbow" axis="0 1 0" damping="0.1" frictionloss="2"/>',
    )
    assert "frictionloss" in text
    path = tmp_path / "arm.xml"
    path.write_text(text)
    report, worst = _actuated(path)
    assert report.status == "fail", worst
    ours = open_with("ours", str(path))
    assert actuated(ours.result, ours.model, 0, TOL).status == "pass"


def test_the_build_is_ours_and_the_report_names_the_loader():
    ours, alone = open_with("ours", str(ARM)), open_with("physx", str(ARM))
    names = [[link.name for link in art.links] for art in ours.result.articulations]
    assert [[link.name for link in art.links] for art in alone.result.articulations] == names
    assert alone.load_info()["loader"] == "physx" and "loader" not in ours.load_info()
