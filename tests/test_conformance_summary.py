"""Judging outcomes against expectations, and atomic writes."""

from __future__ import annotations

import dataclasses
import json
import os

import pytest

from conformance import summary
from conformance.manifest import Expectation, ModelEntry
from conformance.results import ModelResult

SEEN = [{"name": "rollout_zero_qpos", "max": 0.3, "tolerance": 1e-5, "margin": -0.3}]  # inside `_gap`'s band


def _result(status: str, metrics: list | None = None, **tiers: str) -> ModelResult:
    return ModelResult(
        "m", status, tiers={t: {"status": s, "metrics": metrics or [], "notes": []} for t, s in tiers.items()}
    )


def _gap(tier: str = "dynamics", outcome: str = "fail") -> Expectation:
    return Expectation(tier, outcome, "tendons are not mapped", metric="rollout_zero_qpos", seen=0.2)


def test_known_gap_is_expected_fail_and_not_worse():
    entry = ModelEntry(id="m", source="x", tiers=("dynamics",), expect={"dynamics": _gap()})
    (v,) = summary.judge(entry, _result("ok", SEEN, dynamics="fail"))
    assert v.outcome == "expected-fail" and not v.worse
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"m": _result("ok", SEEN, dynamics="fail")})
    assert doc["ok"]
    text = summary.markdown(doc, ["dynamics"])
    assert (
        "| m | expected-fail: rollout_zero_qpos 0.3 " in text and "- m/dynamics (fail): tendons are not mapped" in text
    )


@pytest.mark.parametrize(
    "raw,expected,worse",
    [
        ("pass", "pass", False),
        ("chaotic", "pass", True),
        ("fail", "chaotic", True),
        ("chaotic", "chaotic", False),
        ("pass", "fail", False),
        ("skipped", "pass", True),
    ],
)
def test_worse_than_expected(raw, expected, worse):
    expect = {} if expected == "pass" else {"contact": _gap("contact", expected)}
    entry = ModelEntry(id="m", source="x", tiers=("contact",), expect=expect)
    (v,) = summary.judge(entry, _result("ok", SEEN, contact=raw))
    assert v.worse is worse and v.raw == raw


@pytest.mark.parametrize(
    "raw,worse",
    [("skipped", False), ("chaotic", False), ("fail", True), ("diverged", True), ("error", True), ("pass", False)],
)
def test_a_file_from_the_command_line_may_skip_a_tier_it_rules_out(raw, worse):
    """No manifest names its skips (a model without actuators skips the actuated tiers) or MuJoCo's own chaos: a
    skip or a `chaotic` verdict is not worse there; a failure, a divergence or an error still is. A manifest
    entry's unexpected skip or chaos is worse (`test_worse_than_expected`)."""
    entry = ModelEntry(id="m", source="x", tiers=("actuated",), listed=False)
    (v,) = summary.judge(entry, _result("ok", SEEN, actuated=raw))
    assert v.worse is worse and v.outcome == raw


def test_a_crashed_worker_fails_every_tier():
    entry = ModelEntry(id="m", source="x", tiers=("structure", "dynamics"))
    verdicts = summary.judge(entry, ModelResult("m", "crashed", reason="killed by SIGSEGV"))
    assert [v.outcome for v in verdicts] == ["fail", "fail"] and all(v.worse for v in verdicts)


def test_a_gap_that_closed_is_listed_for_the_manifest_update():
    entry = ModelEntry(id="m", source="x", tiers=("dynamics",), expect={"dynamics": _gap()})
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"m": _result("ok", dynamics="pass")})
    assert doc["ok"] and doc["better_than_expected"] == ["m/dynamics: pass (expected fail)"]
    assert "update its expectations" in summary.markdown(doc, ["dynamics"])


def test_build_flags_the_run(tmp_path):
    entries = [
        ModelEntry(id="a", source="x", tiers=("structure",)),
        ModelEntry(id="b", source="y", tiers=("structure",)),
    ]
    doc = summary.build(
        {"run": "r", "seed": 0, "versions": {}},
        entries,
        {"a": _result("ok", structure="pass"), "b": _result("ok", structure="fail")},
    )
    assert not doc["ok"] and doc["worse_than_expected"] == ["b/structure: fail (expected pass)"]
    json.dumps(doc, allow_nan=False)
    assert "| b | **fail** |" in summary.markdown(doc, ["structure"])


def test_markdown_cell_shows_error_tolerance_and_margin():
    entry = ModelEntry(id="a", source="x", tiers=("inertia",))
    metrics = [
        {"name": "mass", "max": 2e-7, "rms": 1e-7, "tolerance": 1e-5, "margin": 1e-5 - 2e-7, "unit": "relative"},
        {"name": "com", "max": 4e-6, "rms": 1e-6, "tolerance": 5e-6, "margin": 1e-6, "unit": "m"},
    ]
    result = ModelResult("a", "ok", tiers={"inertia": {"status": "pass", "metrics": metrics, "notes": []}})
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"a": result})
    assert "| a | pass: com 4e-06 (tol 5e-06, margin 1e-06) |" in summary.markdown(doc, ["inertia"])


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path, monkeypatch):
    path = tmp_path / "summary.json"
    summary.atomic_write_json(path, {"run": 1})

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError):
        summary.atomic_write_json(path, {"run": 2})
    assert json.loads(path.read_text()) == {"run": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_latest_points_at_the_newest_run(tmp_path):
    for name in ("run1", "run2"):
        (tmp_path / name).mkdir()
        summary.point_latest(tmp_path, tmp_path / name)
    assert os.readlink(tmp_path / "latest") == "run2"


def test_summary_lists_integrator_switch_ctrl_scaling_and_saturation_of_the_actuated_tiers():
    entry = ModelEntry(id="arm", source="x", tiers=("actuated", "actuated_contact"))
    settings = {
        "integrator_authored": "mjINT_EULER",
        "integrator_reference": "mjINT_IMPLICITFAST",
        "ctrl_scale": 0.25,
        "saturated_steps": 3,
        "limit_steps": 0,
    }
    result = ModelResult(
        "arm",
        "ok",
        tiers={
            "actuated": {"status": "pass", "metrics": [], "notes": [], "settings": settings},
            "actuated_contact": {
                "status": "pass",
                "metrics": [],
                "notes": [],
                "settings": {
                    **settings,
                    "integrator_authored": "mjINT_IMPLICITFAST",
                    "ctrl_scale": 1.0,
                    "saturated_steps": 0,
                },
            },
        },
    )
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"arm": result})
    text = summary.markdown(doc, ["actuated", "actuated_contact"])
    assert (
        "- arm/actuated: MuJoCo mjINT_IMPLICITFAST instead of the authored mjINT_EULER; ctrl deviations "
        "scaled by 0.25; forcerange reached on 3 steps (clamped on both sides)"
    ) in text
    assert "- arm/actuated_contact" not in text  # nothing to say: same integrator, no scaling


def test_a_float32_floor_is_subtracted_before_judging_and_the_raw_error_kept():
    from conformance.report import metric

    # errors of 1e-6 and 3e-6 where float32 resolves 2e-6: 0 and 1e-6 are judged, 3e-6 is kept as the raw max
    judged = metric("rollout_qpos", [1e-6, -3e-6], 5e-7, "rad", floor=[2e-6, 2e-6])
    assert (judged.max, judged.raw_max, judged.passed) == (pytest.approx(1e-6), 3e-6, False)
    assert judged.to_dict()["raw_max"] == 3e-6
    assert "raw_max" not in metric("rollout_qpos", [1e-6], 5e-7, "rad").to_dict()
    entry = ModelEntry(id="a", source="x", tiers=("actuated",))
    result = ModelResult("a", "ok", tiers={"actuated": {"status": "fail", "metrics": [judged.to_dict()], "notes": []}})
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"a": result})
    assert "rollout_qpos 1e-06 (raw 3e-06, tol 5e-07" in summary.markdown(doc, ["actuated"])


def test_a_model_result_round_trips_through_json_and_rejects_an_unknown_status():
    import numpy as np

    result = ModelResult(
        "m",
        "ok",
        seconds=np.float64(1.5),
        tiers={"dynamics": {"status": "diverged", "metrics": [{"max": float("nan")}]}},
    )
    doc = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert doc["seconds"] == 1.5 and doc["tiers"]["dynamics"]["metrics"][0]["max"] is None
    assert ModelResult.from_dict({**doc, "written_by": "a later version"}) == ModelResult.from_dict(doc)
    with pytest.raises(ValueError, match="unknown status 'okay'"):
        ModelResult("m", "okay")


PARSE_ERROR = "load failed: ValueError: XML parse error 15:\nError=XML_ERROR_PARSING ErrorID=15 (0xf) Line number=1\n"


def test_a_load_error_is_one_error_outcome():
    entry = ModelEntry(id="m", source="x", tiers=("structure", "dynamics"))
    (v,) = summary.judge(entry, ModelResult("m", "error", reason=PARSE_ERROR))
    assert (v.tier, v.raw, v.expected, v.worse) == ("load", "error", "pass", True)
    doc = summary.build(
        {"run": "r", "seed": 0, "versions": {}}, [entry], {"m": ModelResult("m", "error", reason=PARSE_ERROR)}
    )
    assert not doc["ok"] and doc["worse_than_expected"] == [
        (
            "m/load: error (expected pass): ValueError: XML parse error 15: Error=XML_ERROR_PARSING ErrorID=15 (0xf) "
            "Line number=1"
        )
    ]  # with MuJoCo's message
    assert (
        "| m | **error: ValueError: XML parse error 15: Error=XML_ERROR_PARSING ErrorID=15 (0xf) Line number=1** |  |"
    ) in summary.markdown(doc, ["structure", "dynamics"])


@pytest.mark.parametrize("expected,worse", [("pass", True), ("fail", True), ("error", False)])
def test_an_error_is_worse_than_any_expectation_but_error(expected, worse):
    expect = (
        {"load": Expectation("load", "error", "MuJoCo rejects it")}
        if expected == "error"
        else ({"dynamics": _gap()} if expected == "fail" else {})
    )
    entry = ModelEntry(id="m", source="x", tiers=("dynamics",), expect=expect)
    (v,) = summary.judge(entry, ModelResult("m", "error", reason=PARSE_ERROR))
    assert v.worse is worse


def test_the_headline_is_the_worst_outcome():
    entry = ModelEntry(id="m", source="x", tiers=("structure", "contact", "dynamics"), expect={"dynamics": _gap()})
    result = _result("ok", SEEN, structure="pass", contact="fail", dynamics="fail")
    assert summary.headline("ok", summary.judge(entry, result)) == (
        "fail (expected pass) in contact: rollout_zero_qpos 0.3 (tol 1e-05)"
    )  # the worst metric against its tolerance
    result = _result("ok", SEEN, structure="pass", contact="pass", dynamics="fail")
    assert summary.headline("ok", summary.judge(entry, result)) == (
        "expected-fail in dynamics: rollout_zero_qpos 0.3 (tol 1e-05); tendons are not mapped"
    )  # and the manifest's reason
    assert summary.headline("error", summary.judge(entry, ModelResult("m", "error", reason=PARSE_ERROR))) == (
        "error: ValueError: XML parse error 15: Error=XML_ERROR_PARSING ErrorID=15 (0xf) Line number=1 (expected fail)"
    )  # judged against the model's worst expectation
    assert summary.headline("crashed", summary.judge(entry, ModelResult("m", "crashed"))) == "crashed"
    skipped = ModelResult("m", "ok", tiers={"contact": {"status": "skipped", "metrics": [], "notes": ["no floor"]}})
    listed = ModelEntry(id="m", source="x", tiers=("contact",))
    assert summary.headline("ok", summary.judge(listed, skipped)) == "skipped (expected pass) in contact: no floor"


def test_the_worse_section_says_which_metric_and_why():
    """summary.md's "worse" lines carry the worst metric against its tolerance and the tier's first note."""
    entry = ModelEntry(id="ant", source="x", tiers=("contact",))
    result = ModelResult(
        "ant",
        "ok",
        tiers={
            "contact": {
                "status": "fail",
                "metrics": [{"name": "final_pose_band", "max": 0.12, "tolerance": 0.05, "margin": -0.07}],
                "notes": ["MuJoCo's own spread 0.002 m"],
            }
        },
    )
    doc = summary.build({"run": "r", "seed": 0, "versions": {}}, [entry], {"ant": result})
    assert doc["worse_than_expected"] == [
        "ant/contact: fail (expected pass): final_pose_band 0.12 (tol 0.05); MuJoCo's own spread 0.002 m"
    ]
    assert "- ant/contact: fail (expected pass): final_pose_band 0.12" in summary.markdown(doc, ["contact"])


def _swept_manifest(tmp_path, seeds_line: str, seen: str, more: str = ""):
    from conformance import manifest

    path = tmp_path / "m.toml"
    path.write_text(
        f'[[model]]\nid = "m"\nsource = "fixture:fixtures/pendulum.xml"\n[[model.expect]]\ntier = "dynamics"\n'
        f'outcome = "fail"\nmetric = "rollout_zero_qpos"\nseen = {seen}\n{seeds_line}'
        f'reason = "measured over seeds"\n{more}'
    )
    return dataclasses.replace(manifest.load(path).models[0], tiers=("dynamics",))


def test_an_expectation_scoped_to_seeds_holds_only_there(tmp_path):
    """A failure measured at seeds 1 and 2 only: expected there, and at seed 0 the tier is expected to pass."""
    entry = _swept_manifest(tmp_path, "seeds = [1, 2]\n", "0.2")
    failing = _result("ok", SEEN, dynamics="fail")
    assert [v.outcome for v in summary.judge(entry.at_seed(2), failing)] == ["expected-fail"]
    (v,) = summary.judge(entry.at_seed(0), failing)
    assert v.worse and v.expected == "pass"


def test_a_tier_expected_differently_at_other_seeds_takes_each_seeds_own(tmp_path):
    """Chaotic at seed 0, a failure at seeds 1 and 2: each seed judged against its own; a tier expected twice
    without disjoint seeds is refused."""
    chaotic = '[[model.expect]]\ntier = "dynamics"\noutcome = "chaotic"\nseeds = [0]\nreason = "spread"\n'
    entry = _swept_manifest(tmp_path, "seeds = [1, 2]\n", "0.2", chaotic)
    failing, unpredictable = _result("ok", SEEN, dynamics="fail"), _result("ok", SEEN, dynamics="chaotic")
    (v,) = summary.judge(entry.at_seed(0), unpredictable)
    assert (v.outcome, v.expected, v.worse) == ("chaotic", "chaotic", False)
    assert [v.outcome for v in summary.judge(entry.at_seed(1), failing)] == ["expected-fail"]
    (v,) = summary.judge(entry.at_seed(3), failing)
    assert v.worse and v.expected == "pass"
    for overlapping in ("seeds = [0, 1]\n", ""):
        with pytest.raises(ValueError, match="expected twice"):
            _swept_manifest(tmp_path, overlapping, "0.2", chaotic)


def test_a_range_seen_over_seeds_bands_from_its_low_to_its_high(tmp_path):
    """seen = [0.01, 0.5]: the band runs from 0.001 to 5; a single seen of 0.01 would call 0.3 changed."""
    ranged = _swept_manifest(tmp_path, "", "[0.01, 0.5]")
    (v,) = summary.judge(ranged, _result("ok", SEEN, dynamics="fail"))
    assert v.outcome == "expected-fail"
    single = _swept_manifest(tmp_path, "", "0.01")
    (v,) = summary.judge(single, _result("ok", SEEN, dynamics="fail"))
    assert v.raw == "changed" and v.worse


@pytest.mark.parametrize("seen, seeds", [("[0.5, 0.01]", ""), ("[0.1]", ""), ("0.1", 'seeds = ["one"]\n')])
def test_a_bad_range_or_seed_list_is_rejected(tmp_path, seen, seeds):
    with pytest.raises(ValueError, match="m.toml"):
        _swept_manifest(tmp_path, seeds, seen)


def test_the_readme_table_is_made_from_a_run_and_checked(tmp_path):
    """Pass / judged per tier: a load error is judged and failed everywhere, a skip is not judged, `chaotic` and
    `expected-fail` are judged and not passed. `check` accepts the table made from the run and refuses one number
    off, or a document without the table."""
    from conformance import table

    doc = {
        "seed": 0,
        "models": [
            {"verdicts": {"structure": {"outcome": "pass"}, "contact": {"outcome": "chaotic"}}},
            {"verdicts": {"structure": {"outcome": "pass"}, "contact": {"outcome": "skipped"}}},
            {"verdicts": {"dynamics": {"outcome": "expected-fail"}, "structure": {"outcome": "pass"}}},
            {"verdicts": {"load": {"outcome": "error"}}},
        ],
    }
    numbers = table.counts(doc)
    assert numbers["structure"] == (3, 4) and numbers["contact"] == (0, 2) and numbers["dynamics"] == (0, 2)
    readme = tmp_path / "README.md"
    physx = {**doc, "loader": "physx", "models": doc["models"][:1]}  # PhysX alone: a row of its own
    made = table.table(doc, physx)
    assert made.splitlines()[3:5] == [
        "| this loader (`set_ctrl`) | 3/4 | 0/1 | 0/1 | 0/1 | 0/2 | 0/1 | 0/1 | 0/2 |",
        "| PhysX alone (PD modes, GPU) | 1/1 | 0/0 | 0/0 | 0/0 | 0/1 | 0/0 | 0/0 | 0/0 |",
    ]
    readme.write_text(f"# r\n\n{made}\n\nmore\n")
    assert table.check([doc, physx], readme) is None
    assert "is not these runs'" in table.check([doc], readme)  # a row missing
    readme.write_text(readme.read_text().replace("3/4", "4/4"))
    assert "is not these runs'; replace it with:" in table.check([doc, physx], readme)
    readme.write_text("# r\n")
    assert "has no results table" in table.check([doc], readme)


def test_a_reason_naming_unmapped_elements_is_checked_against_the_notes():
    reason = "8 of its 78 actuators are adhesion actuators on body transmissions, which the loader does not map"
    entry = ModelEntry(
        id="m", source="x", tiers=("actuated",), expect={"actuated": Expectation("actuated", "skipped", reason)}
    )
    dropped = [{"kind": "actuator", "name": f"a{i}", "reason": "body transmission is not mapped"} for i in range(8)]
    result = ModelResult("m", "ok", tiers={"actuated": {"status": "skipped", "metrics": [], "notes": []}})
    (v,) = summary.judge(entry, dataclasses.replace(result, load={"unsupported": dropped}))
    assert not v.worse
    (v,) = summary.judge(entry, dataclasses.replace(result, load={"unsupported": dropped[:7]}))
    assert v.worse and v.detail["notes"][-1] == (
        "stale: the manifest's reason says 8 actuator (the loader drops 7) not mapped; "
        "re-check it against the loader's notes"
    )
    stale = "12 tendons / 4 equalities are not mapped"  # the quadruped's old reason, its elements since mapped
    assert summary.unmapped_mismatch(stale, {"unsupported": [{"kind": "tendon"}] * 12}) == (
        "stale: the manifest's reason says 4 equality (the loader drops 0) not mapped; "
        "re-check it against the loader's notes"
    )
    assert summary.unmapped_mismatch("12 tendons are mapped", {"unsupported": []}) is None  # no claim of a gap
