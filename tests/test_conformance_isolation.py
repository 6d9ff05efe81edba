"""Isolation reruns a failing tier with known gaps removed on both sides; it must explain a real gap (here a
loader that drops frictionloss) and must not explain away a mapping error (a servo kp 5 % off in the loader).
A manifest claim that the run cannot reproduce makes the run fail."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import menagerie_root
from test_tiers_actuated import ARM

import loader.runtime.controller
from conformance import gaps, isolation, tolerances
from conformance.manifest import load as load_manifest
from conformance.results import ModelResult
from conformance.summary import judge

TOL = tolerances.load()
# the actuated-tier arm with a frictionloss on the elbow, which the `dropped_friction` loader does not carry
FRICTION_ARM = ARM.replace('damping="0.02" range="-2 2"', 'damping="0.02" range="-2 2" frictionloss="0.05"')


@pytest.fixture
def friction_arm(tmp_path):
    assert FRICTION_ARM != ARM
    path = tmp_path / "friction_arm.xml"
    path.write_text(FRICTION_ARM)
    return str(path)


@pytest.fixture
def dropped_friction(monkeypatch):
    """The gap to isolate: a loader whose MuJoCo copy solves no friction rows, so SAPIEN's joints slide freely."""
    plan = loader.runtime.controller.plan_rows

    def without_friction(*args):
        term = plan(*args)
        if term is not None:
            term.mirror.dof_frictionloss[:] = 0.0
        return term

    monkeypatch.setattr(loader.runtime.controller, "plan_rows", without_friction)


def test_each_gap_is_removed_from_the_compiled_model(friction_arm):
    base = mujoco.MjModel.from_xml_path(friction_arm)
    assert gaps.present_gaps(base) == ["frictionloss", "limits", "half_timestep"]
    edited = gaps.edited_spec(friction_arm, ("frictionloss", "limits", "half_timestep")).compile()
    assert not edited.dof_frictionloss.any()
    assert edited.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    assert np.isclose(edited.opt.timestep, base.opt.timestep / 2)


FLOATING = """<mujoco><worldbody><body name="root" pos="0 0 1"><freejoint/><geom size=".1"/>
  <body name="arm"><joint name="j" axis="0 1 0"/><geom size=".05" pos=".2 0 0"/></body></body></worldbody>
  <keyframe><key name="up" qpos="0 0 2 1 0 0 0 0.3"/></keyframe></mujoco>"""


def test_a_floating_root_is_welded_only_where_claimed(tmp_path):
    """The `free_root` gap deletes the free joint (the root held where it starts) and the keyframes, whose qpos no
    longer fits; it runs only where an expectation claims it, never among the gaps every failing tier runs."""
    path = tmp_path / "floating.xml"
    path.write_text(FLOATING)
    base = mujoco.MjModel.from_xml_path(str(path))
    assert gaps.GAPS["free_root"].present(base)
    assert "free_root" not in gaps.present_gaps(base)
    welded = gaps.edited_spec(str(path), ("free_root",)).compile()
    assert (welded.njnt, welded.nq, welded.nkey) == (1, 1, 0)
    assert np.allclose(welded.body_pos[1], base.body_pos[1])
    assert not gaps.GAPS["free_root"].present(welded)


def test_tendon_springs_are_zeroed_only_where_claimed():
    """The `tendon_springs` gap zeroes every tendon's stiffness and damping (the fish's fin spring, here), which the
    joint actuation law does not carry; like `free_root`, it runs only where claimed or where a tier asks for it."""
    from support.corpus import suite_path

    path = str(suite_path("fish"))
    base = mujoco.MjModel.from_xml_path(path)
    assert base.tendon_stiffness.any() and gaps.GAPS["tendon_springs"].present(base)
    assert "tendon_springs" not in gaps.present_gaps(base)
    edited = gaps.edited_spec(path, ("tendon_springs",)).compile()
    assert not edited.tendon_stiffness.any() and not edited.tendon_damping.any()
    assert np.array_equal(edited.tendon_lengthspring, base.tendon_lengthspring)


def test_the_tier_fails_with_the_friction_and_passes_without_it(friction_arm, dropped_friction):
    full = isolation.run_without(friction_arm, "actuated", (), 0, TOL)
    assert full["outcome"] == "fail"
    without = isolation.run_without(friction_arm, "actuated", ("frictionloss",), 0, TOL)
    assert without["outcome"] == "pass", without
    assert isolation.claim_holds([full, without], ("frictionloss",))


def test_a_kp_error_survives_every_isolation(friction_arm, dropped_friction, monkeypatch):
    """The mutation: the loader's servo stiffness 5 % high. Removing the friction no longer makes it pass."""
    plan = loader.runtime.controller.plan_actuators

    def stiffer(*args):
        term = plan(*args)
        for law in term.laws.values():
            law.stiffness *= 1.05 if law.stiffness > 0 else 1.0
        return term

    monkeypatch.setattr(loader.runtime.controller, "plan_actuators", stiffer)
    runs = isolation.isolate(friction_arm, mujoco.MjModel.from_xml_path(friction_arm), "actuated", 0, TOL)
    assert runs and all(r["outcome"] == "fail" for r in runs), runs
    assert not isolation.claim_holds(runs, ("frictionloss",))


def _manifest(tmp_path, claim: str) -> object:
    path = tmp_path / "manifest.toml"
    path.write_text(
        f'[[model]]\nid = "arm"\nsource = "arm.xml"\n[[model.expect]]\ntier = "actuated"\n'
        f'outcome = "fail"\nmetric = "one_step_qvel"\nseen = 0.01\nreason = "frictionloss"\n'
        f"passes_without = {claim}\n"
    )
    return load_manifest(path)


def test_a_claim_the_run_cannot_reproduce_is_worse_than_expected(tmp_path):
    entry = _manifest(tmp_path, '["frictionloss"]').models[0]
    failing = {
        "status": "fail",
        "metrics": [{"name": "one_step_qvel", "max": 0.02, "tolerance": 1e-5}],
        "notes": [],
        "isolation": [{"without": ["frictionloss"], "outcome": "fail", "metrics": []}],
    }
    verdict = next(
        v for v in judge(entry, ModelResult("arm", "ok", tiers={"actuated": failing})) if v.tier == "actuated"
    )
    assert verdict.worse and verdict.outcome == "fail"
    holding = {**failing, "isolation": [{"without": ["frictionloss"], "outcome": "pass", "metrics": []}]}
    verdict = next(
        v for v in judge(entry, ModelResult("arm", "ok", tiers={"actuated": holding})) if v.tier == "actuated"
    )
    assert not verdict.worse and verdict.outcome == "expected-fail"


def test_a_claim_naming_an_unknown_gap_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="passes_without"):
        _manifest(tmp_path, '["gravity"]')


def test_the_worker_records_the_isolation_in_the_result_and_the_recording(friction_arm, dropped_friction, tmp_path):
    from test_rerun_recording import read_rrd

    from conformance.manifest import ModelEntry
    from conformance.worker import Job, evaluate

    entry = ModelEntry(id="friction_arm", source=friction_arm, tiers=("actuated",))
    result = evaluate(Job(entry, friction_arm, str(tmp_path), 0, entry.tiers, record=True))
    runs = result.tiers["actuated"]["isolation"]
    assert result.tiers["actuated"]["status"] == "fail"
    assert {"without": ["frictionloss"], "outcome": "pass"}.items() <= next(
        r for r in runs if r["without"] == ["frictionloss"]
    ).items()
    text = read_rrd(tmp_path / "friction_arm.rrd")["/verdict"]["TextDocument:text"][-1][0]
    assert "## Isolation" in text and "without frictionloss: pass" in text


def test_the_uncoupled_equality_gap_keeps_what_the_law_carries():
    """The Robotiq gripper's two connects (a loop on its fixed base) and its joint coupling are the joint actuation
    law's: no gap. Given a weld of a pad to the world too, the weld goes (deactivated on both sides) and the rest
    stays: the gap the `maniskill_tensor` tier takes out. The panda, whose one equality is a coupling, has no such
    gap."""
    root = menagerie_root()
    if root is None:
        pytest.skip("Menagerie slice not installed (extra 'menagerie')")
    spec = mujoco.MjSpec.from_file(str(root / "robotiq_2f85_v4/2f85.xml"))
    assert not gaps.GAPS["uncoupled_equality"].present(spec.compile())
    spec.add_equality(type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY, name1="left_pad")  # to the world
    welded = spec.compile()
    assert gaps.GAPS["uncoupled_equality"].present(welded)
    edited = gaps.without(spec, ("uncoupled_equality",)).compile()
    assert [bool(a) for a in edited.eq_active0] == [int(t) != int(mujoco.mjtEq.mjEQ_WELD) for t in edited.eq_type]
    assert not gaps.GAPS["uncoupled_equality"].present(edited)
    panda = mujoco.MjModel.from_xml_path(str(root / "franka_emika_panda/panda.xml"))
    assert panda.neq and not gaps.GAPS["uncoupled_equality"].present(panda)
