"""A SAPIEN run that blows up is `diverged`, worse than any expectation; an expected failure whose metric leaves
the band its reason was measured in is `changed`, also worse (conformance/divergence.py, conformance/summary.py)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from support.cli import run_selftest

from conformance import summary
from conformance.divergence import SpeedBound, first_divergence
from conformance.manifest import BAND_FACTOR, Expectation, ModelEntry
from conformance.report import Metric, judged, verdict
from conformance.results import ModelResult

BOUND = SpeedBound(factor=10.0, floor=100.0)
DT = 0.002


def _run(speeds: list[float]) -> tuple[np.ndarray, np.ndarray]:
    qvel = np.array([[s, 0.0] for s in speeds])
    return np.zeros((len(speeds), 3)), qvel


def test_a_nan_state_is_found_at_its_first_step():
    qpos, qvel = _run([1.0, 2.0, 3.0, 4.0])
    qpos[2, 1] = np.nan
    found = first_divergence("rollout zero", qpos, qvel, np.ones(4), BOUND, DT)
    assert found is not None and found.step == 2 and found.what == "qpos not finite"
    assert found.time == pytest.approx(2 * DT)
    assert found.text() == "rollout zero step 2 (t = 0.004 s): qpos not finite"


def test_a_finite_run_within_the_bound_has_not_diverged():
    qpos, qvel = _run([99.0, -99.0])
    assert first_divergence("settle", qpos, qvel, np.zeros(2), BOUND, DT) is None


@pytest.mark.parametrize(
    "mujoco_fastest,sapien,diverged",
    [
        (1.0, 99.0, False),
        (1.0, 101.0, True),  # the floor: 100 rad/s
        (20.0, 199.0, False),
        (20.0, 201.0, True),  # 10x MuJoCo's fastest in the same run
        (20.0, -201.0, True),  # either direction
    ],
)
def test_the_speed_bound_is_the_floor_or_ten_times_mujocos_fastest(mujoco_fastest, sapien, diverged):
    qpos, qvel = _run([0.0, sapien])
    found = first_divergence("rollout", qpos, qvel, [0.0, mujoco_fastest], BOUND, DT, steps=[10, 20])
    assert (found is not None) is diverged
    if diverged:
        assert found.step == 20 and "above the bound" in found.what


def test_one_step_samples_report_their_own_step_numbers():
    qpos, qvel = _run([1.0, np.inf])
    found = first_divergence("one-step", qpos, qvel, [1.0], BOUND, DT, steps=[1, 11])
    assert found.step == 11 and found.what == "qvel not finite"


def test_a_divergence_or_a_non_finite_metric_outranks_every_other_status():
    good = Metric("rollout_qpos", 1e-7, 1e-7, 1e-5, "rad")
    bad = Metric("rollout_qpos", 1.0, 1.0, 1e-5, "rad")
    found = first_divergence("rollout", *_run([np.nan]), [0.0], BOUND, DT)
    assert verdict([good]) == "pass" and verdict([bad]) == "fail" and verdict([good], chaotic=True) == "chaotic"
    assert verdict([good], divergence=found) == "diverged"
    assert verdict([good, Metric("one_step_qvel", float("inf"), float("inf"), 1e-5, "rad/s")]) == "diverged"


def test_an_infinite_error_of_a_static_tier_is_a_mapping_failure_not_a_divergence():
    infinite = Metric("limit", float("inf"), float("inf"), 1e-6, "rad")  # a finite range mapped as unlimited
    assert verdict([infinite], simulated=False) == "fail"
    assert judged("structure", [infinite]).status == "fail"
    assert judged("structure", [Metric("limit", 1e-8, 1e-8, 1e-6, "rad")]).status == "pass"


def _entry(seen: float) -> ModelEntry:
    return ModelEntry(
        id="m",
        source="x",
        tiers=("dynamics",),
        expect={"dynamics": Expectation("dynamics", "fail", "a known gap", metric="rollout_zero_qpos", seen=seen)},
    )


def _measured(value: float | None, status: str = "fail", divergence: dict | None = None) -> ModelResult:
    report = {
        "status": status,
        "metrics": [{"name": "rollout_zero_qpos", "max": value, "tolerance": 1e-5}],
        "notes": [],
    }
    if divergence:
        report["divergence"] = divergence
    return ModelResult("m", "ok", tiers={"dynamics": report})


@pytest.mark.parametrize(
    "factor,outcome",
    [
        (1.0, "expected-fail"),
        (0.9 * BAND_FACTOR, "expected-fail"),
        (1 / (0.9 * BAND_FACTOR), "expected-fail"),
        (1.1 * BAND_FACTOR, "changed"),
        (1 / (1.1 * BAND_FACTOR), "changed"),
    ],
)
def test_an_expected_failure_outside_its_band_is_changed(factor, outcome):
    (v,) = summary.judge(_entry(0.02), _measured(0.02 * factor))
    assert v.outcome == outcome and v.worse is (outcome == "changed")
    if outcome == "changed":
        assert "re-measure the reason" in v.detail["notes"][-1]


def test_an_expected_failure_without_its_metric_is_changed():
    (v,) = summary.judge(_entry(0.02), _measured(None))
    assert v.outcome == "changed" and v.worse


def test_a_divergence_is_worse_than_an_expected_failure_and_names_its_step():
    where = {"run": "settle", "step": 151, "time": 0.755, "what": "qpos and qvel not finite"}
    doc = summary.build(
        {"run": "r", "seed": 0, "versions": {}}, [_entry(0.02)], {"m": _measured(None, "diverged", where)}
    )
    assert not doc["ok"]
    assert doc["worse_than_expected"] == [
        "m/dynamics: diverged (expected fail): settle step 151 (t = 0.755 s): qpos and qvel not finite"
    ]
    assert "| m | **diverged: settle step 151" in summary.markdown(doc, ["dynamics"])
    (v,) = summary.judge(_entry(0.02), _measured(None, "diverged", where))
    assert summary.headline("ok", [v]) == (
        "diverged (expected fail) in dynamics at settle step 151 (t = 0.755 s): qpos and qvel not finite"
    )


@pytest.mark.parametrize(
    "body,message",
    [
        ('outcome = "diverged"\nreason = "r"', "outcome in"),
        ('outcome = "changed"\nreason = "r"', "outcome in"),
        ('outcome = "fail"\nreason = "r"', "names the `metric`"),
        ('outcome = "fail"\nmetric = "rollout_zero_qpos"\nseen = 0\nreason = "r"', "positive max `seen`"),
    ],
)
def test_the_manifest_cannot_expect_what_only_a_run_can_say(tmp_path, body, message):
    from conformance import manifest

    path = tmp_path / "m.toml"
    path.write_text(f'[[model]]\nid = "m"\nsource = "x.xml"\n[[model.expect]]\ntier = "dynamics"\n{body}\n')
    with pytest.raises(ValueError, match=message):
        manifest.load(path)


def _selftest(model: str, tmp_path: Path) -> tuple[subprocess.CompletedProcess, dict]:
    proc = run_selftest(model, tmp_path)
    return proc, json.loads((tmp_path / "latest" / "summary.json").read_text())


def test_a_rollout_gone_nan_fails_the_run_whatever_the_manifest_expected(tmp_path):
    """The selftest model `nan` expects its dynamics tier to fail; its worker poisons SAPIEN's velocities after five
    steps (`fault = "nan"`), so PhysX carries NaN into the poses."""
    proc, doc = _selftest("nan", tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    verdict_ = doc["models"][0]["verdicts"]["dynamics"]
    assert verdict_["outcome"] == "diverged" and verdict_["worse_than_expected"]
    assert verdict_["divergence"]["what"].endswith("not finite")
    assert doc["worse_than_expected"][0].startswith("nan/dynamics: diverged (expected fail): one-step step ")
    assert "diverged" in proc.stdout


def test_an_expected_failure_whose_metric_moved_fails_the_run_as_changed(tmp_path):
    """The selftest model `band` fails on a tolerance below float32's resolution; its manifest entry says it was seen
    at 1.0 rad/s, far above what the run measures."""
    proc, doc = _selftest("band", tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    verdict_ = doc["models"][0]["verdicts"]["dynamics"]
    assert verdict_["outcome"] == "changed" and verdict_["worse_than_expected"]
    assert "left the band [0.1, 10]" in doc["worse_than_expected"][0]


def test_the_recordings_verdict_panel_names_the_first_bad_step():
    from conformance.recording import verdict_markdown
    from conformance.report import TierReport

    found = first_divergence("rollout zero", *_run([1.0, np.nan]), [1.0], BOUND, DT)
    report = TierReport(
        "dynamics", "diverged", [Metric("rollout_zero_qpos", np.inf, np.inf, 1e-5, "rad")], divergence=found
    )
    text = verdict_markdown({"dynamics": report}, {"model": "m"})
    assert "| dynamics | diverged | first bad step: rollout zero step 1 (t = 0.002 s): qvel not finite |" in text
