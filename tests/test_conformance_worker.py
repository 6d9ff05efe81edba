"""A worker evaluates one model: manifest overrides reach the tiers, and the result is plain JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from conformance.manifest import ModelEntry
from conformance.worker import Job, evaluate

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "corpus" / "fixtures" / "pendulum.xml"


def _evaluate(tmp_path, **entry):
    model = ModelEntry(id="pendulum", source="fixture:fixtures/pendulum.xml", **entry)
    return evaluate(Job(model, str(FIXTURE), str(tmp_path), 0, model.tiers, record=False))


def test_result_is_json_with_versions_settings_and_load_notes(tmp_path):
    result = _evaluate(tmp_path, tiers=("structure", "dynamics"))
    json.dumps(result.to_dict(), allow_nan=False)
    assert result.status == "ok" and set(result.tiers) == {"structure", "dynamics"}
    assert result.settings["sapien"]["solver"] == "PGS"
    assert result.settings["sapien"]["timestep"] == pytest.approx(
        result.settings["mujoco"]["timestep"], rel=1e-6
    )  # SAPIEN stores float32
    assert result.load["load_seconds"] > 0 and result.versions["rerun-sdk"]


def test_manifest_overrides_reach_the_tiers(tmp_path):
    result = _evaluate(
        tmp_path,
        tiers=("kinematics", "dynamics"),
        tolerances={"kinematics.position": 1e-12},
        settings={"dynamics": {"horizon_s": 0.02}},
        override_reason="test",
    )
    kinematics = result.tiers["kinematics"]
    assert kinematics["status"] == "fail"
    assert next(m for m in kinematics["metrics"] if m["name"] == "position")["tolerance"] == 1e-12
    assert result.tiers["dynamics"]["settings"]["steps"] == 10  # 0.02 s at dt = 0.002


def test_a_file_the_loader_rejects_is_that_models_error(tmp_path):
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>")
    model = ModelEntry(id="broken", source=str(broken))
    result = evaluate(Job(model, str(broken), str(tmp_path), 0, model.tiers, record=False))
    assert result.status == "error" and "load failed" in result.reason


def test_actuated_tiers_run_in_order_before_dynamics_and_leave_it_a_clean_scene(tmp_path):
    from test_tiers_actuated import ARM

    arm = tmp_path / "arm.xml"
    arm.write_text(ARM)
    model = ModelEntry(id="arm", source=str(arm), tiers=("dynamics", "actuated", "actuated_contact", "contact"))
    result = evaluate(Job(model, str(arm), str(tmp_path), 0, model.tiers, record=False))
    json.dumps(result.to_dict(), allow_nan=False)
    assert list(result.tiers) == ["contact", "actuated_contact", "actuated", "dynamics"]
    assert {t: r["status"] for t, r in result.tiers.items()} == {
        "contact": "pass",
        "actuated_contact": "pass",
        "actuated": "pass",
        "dynamics": "pass",
    }
    actuated = result.tiers["actuated"]["settings"]
    assert actuated["integrator_reference"] == "mjINT_EULER" and actuated["actuators"] is True  # as authored
    assert result.tiers["dynamics"]["settings"]["actuators"] is False  # its reference disables actuation
