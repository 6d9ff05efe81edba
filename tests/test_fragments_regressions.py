"""Every shrunk counterexample in corpus/regressions/ is replayed with all the properties, strictly (no known-bug
excuse, a tier that raises fails). Files of bugs still open are strict xfails with the reason on record."""

from __future__ import annotations

import pytest

from conformance.fragments import check_path
from conformance.fragments.regressions import REGRESSIONS, known_bugs, regression_files, terms_bugs

KNOWN = known_bugs(REGRESSIONS)
TERMS = terms_bugs(REGRESSIONS)


def _params():
    """Each file under the loader's default law; a bug of the terms' law alone, under the terms too (`terms`)."""
    for path in regression_files(REGRESSIONS):
        reason = KNOWN.get(path.name)
        xfail = [pytest.mark.xfail(strict=True, reason=" ".join(reason.split()))] if reason else []
        if path.name in TERMS:
            yield pytest.param(path, "default", id=path.stem)
            yield pytest.param(path, "terms", id=f"{path.stem}-terms", marks=xfail)
        else:
            yield pytest.param(path, "default", id=path.stem, marks=xfail)


@pytest.mark.parametrize("path, law", list(_params()))
def test_regression_replays_clean(path, law, request):
    if law == "terms":
        request.getfixturevalue("terms")
    outcome = check_path(path, strict=True)
    assert not outcome.failures, "\n".join(outcome.failures)


def test_every_known_bug_has_its_file():
    names = {path.name for path in regression_files(REGRESSIONS)}
    assert set(KNOWN) <= names, set(KNOWN) - names


def test_dynamics_tier_reports_on_a_singular_mass_matrix():
    """Two hinges on one axis make the joint-space inertia singular; the tier still returns a report."""
    from conformance.fragments.properties import load, tolerances
    from conformance.tiers import TIERS

    result = load(REGRESSIONS / "coincident_hinges_singular_mass_matrix.xml")
    report = TIERS["dynamics"](result, result.model, 0, tolerances())
    assert report.status in ("pass", "fail", "chaotic", "skipped")


def test_every_open_bug_detector_names_a_known_bug():
    from conformance.fragments.known_bugs import KNOWN_BUGS

    assert {bug.regression for bug in KNOWN_BUGS} <= set(KNOWN)
    assert {bug.regression for bug in KNOWN_BUGS if bug.terms_only} == TERMS  # the terms' bugs, said once each side


@pytest.mark.parametrize(
    "find, detector, change, detector_silent_after",
    [
        ("slender_rod_about_its_axis", "_slender_about_a_hinge", ('euler="0 35 0"', 'euler="0 0 0"'), False),
        ("robot_classes-1fb34010df", "_servo_spins_fast", ('kp="5"', 'kp="0.5"'), True),
        ("conformance-c24daadc9b", "_slide_far_from_its_zero", ('ref="-20"', 'ref="0"'), True),
        ("robot_classes-3829e85071", "_unconverged_started_past_its_end", (' iterations="1"', ""), True),
        ("robot_classes-c02fcfd7fc", "_light_link_started_past_its_end", ('qpos="-1.5 ', 'qpos="-0.5 '), False),
    ],
)
def test_a_known_bugs_find_passes_without_the_trait_its_detector_names(
    tmp_path, find, detector, change, detector_silent_after
):
    """The attribution of a known bug: its detector names the find, and the same document with only that trait
    undone (the body back on the world axes) passes every property."""
    import shutil

    import mujoco

    from conformance.fragments import known_bugs

    triggers = getattr(known_bugs, detector)
    path = REGRESSIONS / f"{find}.xml"
    assert triggers(None, mujoco.MjModel.from_xml_path(str(path)))
    for mesh in REGRESSIONS.glob(f"{find}.*.obj"):
        shutil.copy(mesh, tmp_path)
    variant = tmp_path / path.name
    text = path.read_text()
    assert change[0] in text
    variant.write_text(text.replace(*change))
    if detector_silent_after:
        assert not triggers(None, mujoco.MjModel.from_xml_path(str(variant)))
    assert not check_path(variant, strict=True).failures


def test_a_known_bug_excuses_a_divergence_only_where_its_finds_diverge(monkeypatch):
    """robot_classes-c02fcfd7fc.xml diverges in the actuated tier: the fuzz files it under its known bug, whose finds
    diverge (`KnownBug.diverges`); the same bug without that mark leaves it a failure."""
    import dataclasses

    import mujoco

    from conformance.fragments import known_bugs
    from conformance.fragments.properties import check_tiers, load

    path = REGRESSIONS / "robot_classes-c02fcfd7fc.xml"
    result, model = load(path), mujoco.MjModel.from_xml_path(str(path))
    _, failures, excused, _, _ = check_tiers(result, model, tiers=())
    assert not failures
    assert any("known bug robot_classes-290ddd7193.xml (diverged:" in e for e in excused), excused
    unmarked = [dataclasses.replace(bug, diverges=False) for bug in known_bugs.KNOWN_BUGS]
    monkeypatch.setattr(known_bugs, "KNOWN_BUGS", unmarked)
    _, failures, _, _, _ = check_tiers(load(path), model, tiers=())
    assert any("actuated tier diverged" in f for f in failures), failures


def test_a_terms_bug_is_no_excuse_where_mujocos_own_step_runs():
    """robot_classes-290ddd7193.xml replays clean under MuJoCo's own step (its default law) and fails under the
    terms: its known bug excuses a failure only where the terms run (`KnownBug.terms_only`), so a failure of
    MuJoCo's step on a model of that class is never filed under it. Mutation: the mark dropped."""
    import dataclasses

    import mujoco

    from conformance.fragments import known_bugs
    from conformance.fragments.properties import load

    path = REGRESSIONS / "robot_classes-290ddd7193.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    stepped, terms = load(path), load(path)
    terms.controller.use_mujoco_step(False)
    assert stepped.controller.law() == "mujoco_step" and terms.controller.law().startswith("terms")
    assert known_bugs.known_bug("actuated", terms, model) == path.name
    assert known_bugs.known_bug("actuated", stepped, model) is None
    unmarked = [dataclasses.replace(bug, terms_only=False) for bug in known_bugs.KNOWN_BUGS]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(known_bugs, "KNOWN_BUGS", unmarked)
        assert known_bugs.known_bug("actuated", stepped, model) == path.name
