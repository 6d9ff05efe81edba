"""The runner isolates every model in a worker: a crash or a hang fails that model, the run completes,
the exit status reflects it, and summaries are written atomically."""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from support.cli import ROOT, SELFTEST, run_cli, run_selftest


@pytest.fixture(scope="module")
def selftest_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reports")
    started = time.monotonic()
    # the harness pendulum has no actuators: its actuated tiers would be skipped, which counts as worse than the
    # selftest manifest's "pass" (they run in test_conformance_worker.py and test_tiers_actuated.py)
    proc = run_cli(
        "--manifest",
        str(SELFTEST),
        "--out",
        str(out),
        "--jobs",
        "2",
        "--quiet",
        "--tiers",
        "structure,kinematics,inertia,collision,contact,dynamics",
    )
    elapsed = time.monotonic() - started
    latest = out / "latest"
    return proc, out, latest.resolve(), json.loads((latest / "summary.json").read_text()), elapsed


def _model(summary: dict, model_id: str) -> dict:
    return next(m for m in summary["models"] if m["id"] == model_id)


def test_crash_is_that_models_failure(selftest_run):
    _, _, _, summary, _ = selftest_run
    crash = _model(summary, "crash")
    assert crash["status"] == "crashed"
    assert "SIGSEGV" in crash["reason"]
    assert {v["outcome"] for v in crash["verdicts"].values()} == {"fail"}


def test_hang_is_killed_at_its_timeout(selftest_run):
    _, _, _, summary, elapsed = selftest_run
    hang = _model(summary, "hang")
    assert hang["status"] == "timeout"
    assert "3 s timeout" in hang["reason"]
    assert {v["outcome"] for v in hang["verdicts"].values()} == {"fail"}
    assert elapsed < 120, "the hung worker must not hold the run"


def test_the_rest_of_the_run_completes(selftest_run):
    _, _, run_dir, summary, _ = selftest_run
    pendulum = _model(summary, "pendulum")
    assert pendulum["status"] == "ok"
    assert {v["outcome"] for v in pendulum["verdicts"].values()} == {"pass"}
    assert (run_dir / "pendulum.rrd").stat().st_size > 0
    assert not (run_dir / "crash.rrd").exists()


def test_missing_source_is_skipped_with_reason_never_passed(selftest_run):
    _, _, _, summary, _ = selftest_run
    missing = _model(summary, "missing")
    assert missing["status"] == "skipped"
    assert "does_not_exist.xml" in missing["reason"]
    assert {v["outcome"] for v in missing["verdicts"].values()} == {"skipped"}


def test_exit_status_is_nonzero_exactly_when_worse_than_expected(selftest_run, tmp_path):
    proc, _, _, summary, _ = selftest_run
    assert proc.returncode == 1, proc.stderr
    assert not summary["ok"]
    assert any(w.startswith("crash/") for w in summary["worse_than_expected"])
    assert not any(w.startswith("pendulum/") for w in summary["worse_than_expected"])
    # the healthy fixture alone meets every expectation
    ok = run_selftest("pendulum", tmp_path, "--tiers", "structure,kinematics")
    assert ok.returncode == 0, ok.stdout + ok.stderr


def test_summary_records_versions_and_markdown_table(selftest_run):
    _, _, run_dir, summary, _ = selftest_run
    assert set(summary["versions"]) == {"mujoco", "sapien", "rerun-sdk", "dm-control", "numpy", "python"}
    text = (run_dir / "summary.md").read_text()
    assert "| crash |" in text and "| pendulum |" in text
    assert not list(run_dir.glob(".*")), "no temporary files are left behind"


def test_interrupted_run_keeps_a_valid_summary_and_earlier_runs(selftest_run, tmp_path):
    _, out, earlier, _, _ = selftest_run
    before = {p.name: p.read_bytes() for p in earlier.iterdir() if p.is_file()}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "conformance",
            "run",
            "--manifest",
            str(SELFTEST),
            "--model",
            "hang",
            "--out",
            str(out),
            "--quiet",
            "--timeout-scale",
            "100",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    runs = set()
    while time.monotonic() < deadline and not runs:
        runs = {
            p
            for p in out.iterdir()
            if p.is_dir() and not p.is_symlink() and p != earlier and (p / "summary.json").exists()
        }
        time.sleep(0.2)
    if not runs:
        proc.kill()
        out_text, err_text = proc.communicate(timeout=60)
        raise AssertionError(f"the run never wrote its first summary (exit {proc.returncode}): {out_text} {err_text}")
    time.sleep(3)  # the worker is now hanging
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=60)
    assert proc.returncode == 130
    (run,) = runs
    summary = json.loads((run / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert {p.name: p.read_bytes() for p in earlier.iterdir() if p.is_file()} == before
    assert os.readlink(out / "latest") == run.name


def test_mjcf_paths_on_the_command_line(tmp_path):
    proc = run_cli(
        str(ROOT / "corpus" / "fixtures" / "pendulum.xml"),
        "--out",
        str(tmp_path),
        "--quiet",
        "--tiers",
        "structure,inertia",
        "--seed",
        "5",
        "--jobs",
        "1",
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((tmp_path / "latest" / "summary.json").read_text())
    assert summary["seed"] == 5 and summary["tiers"] == ["structure", "inertia"]
    (model,) = summary["models"]
    assert model["id"] == "pendulum" and set(model["verdicts"]) == {"structure", "inertia"}
    assert (tmp_path / "latest" / "pendulum.rrd").exists()


USAGE_ERRORS = {
    "a missing path": (["{tmp}/nothere.xml"], "nothere.xml: no such file or folder"),
    "a folder without .xml files": (["{tmp}/empty"], "empty: a folder without .xml files"),
    "an unknown model": (["--manifest", str(SELFTEST), "--model", "nope"], "no model ['nope']"),
    "an unknown named corpus": (["--corpus", "nosuch"], "no corpus 'nosuch'"),
    "an unknown tier": (["--tiers", "physics"], "unknown tiers ['physics']"),
    "a missing manifest": (["--manifest", "{tmp}/none.toml"], "none.toml"),
    "a manifest that is not TOML": (["--manifest", "{tmp}/broken.toml"], "Expected"),
    "paths and --model together": (["{tmp}/empty", "--model", "cartpole"], "give one or the other"),
    "a seed range backwards": (["--seeds", "3..1"], "'3..1': give an inclusive range A..B with A <= B"),
    "a seed range that is not one": (["--seeds", "0-3"], "'0-3': give an inclusive range A..B of integers"),
    "--seed and --seeds together": (["--seed", "2", "--seeds", "0..1"], "give one or the other"),
    "an unknown executor": (["--executor", "spark"], "unknown executor 'spark'"),
}


@pytest.mark.parametrize("case", USAGE_ERRORS)
def test_a_usage_error_exits_2_names_the_problem_and_writes_nothing(tmp_path, case):
    args, message = USAGE_ERRORS[case]
    (tmp_path / "empty").mkdir()
    (tmp_path / "broken.toml").write_text("[[model]\nid = ")
    proc = run_cli(*[a.format(tmp=tmp_path) for a in args], "--out", str(tmp_path / "out"), "--quiet", "--no-record")
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists(), "a usage error writes nothing"


def test_an_unknown_named_corpus_lists_the_known_ones(tmp_path):
    proc = run_cli("--corpus", "nosuch", "--out", str(tmp_path), "--quiet", "--no-record")
    assert "named corpora: full" in proc.stderr


def test_version_and_help_show_what_a_newcomer_needs():
    import mujoco

    version = subprocess.run(
        [sys.executable, "-m", "conformance", "--version"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert version.returncode == 0 and version.stdout.startswith("mjcf-sapien ")
    assert f"mujoco {mujoco.__version__}" in version.stdout
    helped = run_cli("--help")
    text = " ".join(helped.stdout.split())
    assert helped.returncode == 0
    assert "one <run>/ folder per run" in text and "(default: reports)" in text and "--seed SEED seed of" in text
    assert "seed of configurations and commands (default: 0)" in text


def test_summary_files_are_readable_by_everyone(tmp_path):
    proc = run_selftest("pendulum", tmp_path, "--tiers", "structure", preexec_fn=lambda: os.umask(0o022))
    assert proc.returncode == 0, proc.stderr
    run = (tmp_path / "latest").resolve()
    written = [run / "summary.json", run / "summary.md", run / "models" / "pendulum.json"]
    assert {p.name: oct(p.stat().st_mode & 0o777) for p in written} == {p.name: "0o644" for p in written}


DEPRECATED = """<mujoco model="heavy"><compiler settotalmass="2"/>
  <worldbody><body><joint type="hinge"/><geom size="0.1" fromto="0 0 0 0 0 -0.3" type="capsule"/></body></worldbody>
</mujoco>"""


def test_third_party_warnings_are_counted_not_printed(tmp_path):
    (tmp_path / "heavy.xml").write_text(DEPRECATED)  # MuJoCo warns at compile: settotalmass is deprecated
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = run_cli(
        str(tmp_path / "heavy.xml"),
        "--out",
        str(tmp_path / "out"),
        "--no-record",
        "--tiers",
        "structure,inertia",
        cwd=elsewhere,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr
    terminal = proc.stdout + proc.stderr
    assert "settotalmass" not in terminal and "libvulkan" not in terminal and "Warning:" not in terminal
    assert "third-party warnings: " in proc.stdout and " in 1 models, counted by kind in summary.json" in proc.stdout
    run = (tmp_path / "out" / "latest").resolve()
    (model,) = json.loads((run / "summary.json").read_text())["models"]
    assert any(k.startswith("MuJoCo: compiler attribute 'settotalmass'") for k in model["warnings"])
    assert "settotalmass" in (run / "MUJOCO_LOG.TXT").read_text()
    assert not list(elsewhere.iterdir()), "MuJoCo's log goes into the run folder, not the working directory"


def test_malformed_xml_is_one_error_outcome_with_mujocos_message(tmp_path):
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body><geom size='0.1'/></body></worldbody>")  # unclosed
    proc = run_cli(str(tmp_path / "broken.xml"), "--out", str(tmp_path / "out"), "--quiet", "--no-record")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "broken  WORSE  error: ValueError: XML parse error" in proc.stdout
    summary = json.loads((tmp_path / "out" / "latest" / "summary.json").read_text())
    (model,) = summary["models"]
    assert list(model["verdicts"]) == ["load"] and model["verdicts"]["load"]["outcome"] == "error"
    assert "| broken | **error: ValueError: XML parse error" in (tmp_path / "out" / "latest" / "summary.md").read_text()


def test_a_path_that_is_a_manifest_model_takes_the_manifests_expectations(tmp_path):
    from conformance.corpus import dm_control_suite_dir

    # cartpole disables contact: its contact tier is skipped, which the default manifest expects
    cartpole = dm_control_suite_dir() / "cartpole.xml"
    by_path = run_cli(str(cartpole), "--out", str(tmp_path / "a"), "--quiet", "--no-record", "--tiers", "contact")
    by_id = run_cli("--model", "cartpole", "--out", str(tmp_path / "b"), "--quiet", "--no-record", "--tiers", "contact")
    assert (by_path.returncode, by_id.returncode) == (0, 0), by_path.stdout + by_id.stdout
    assert by_path.stdout.splitlines()[0] == by_id.stdout.splitlines()[0]
    assert by_path.stdout.startswith("cartpole  ok     skipped in contact")


THREE_CYLINDERS = """<mujoco model="rack"><worldbody><body><joint axis="0 1 0"/>
  <geom type="cylinder" size=".05 .1"/><geom type="cylinder" size=".05 .1" pos=".2 0 0"/>
  <geom type="cylinder" size=".05 .1" pos=".4 0 0"/></body></worldbody></mujoco>"""


def test_the_terminal_gets_one_line_per_model_and_the_file_the_table(tmp_path):
    (tmp_path / "rack.xml").write_text(THREE_CYLINDERS)  # each cylinder is a convex approximation in PhysX
    args = (str(tmp_path / "rack.xml"), "--quiet", "--no-record", "--tiers", "structure")
    plain = run_cli(*args, "--out", str(tmp_path / "a"))
    assert plain.returncode == 0, plain.stderr
    run = (tmp_path / "a" / "latest").resolve()
    assert plain.stdout.splitlines() == [
        "rack  ok     pass  (loader: approximated geom 3)",
        "1 models, 0 worse than the manifest expects",
        f"report: {run / 'summary.md'} (outcomes and notes explained: reports/README.md)",
    ]
    assert "| rack | pass" in (run / "summary.md").read_text()
    detailed = run_cli(*args, "--out", str(tmp_path / "b"), "-v").stdout.splitlines()
    notes = [line for line in detailed if line.startswith("    approximated geom ")]
    assert len(notes) == 3 and all("cylinder" in line for line in notes)


def _kinematics(model: dict) -> dict:
    """A model's kinematics metrics by name (their max): what a seed changes (the sampled configurations)."""
    return {m["name"]: m["max"] for m in model["verdicts"]["kinematics"]["metrics"]}


def test_a_seed_sweep_runs_each_model_once_per_seed(tmp_path):
    args = ("--manifest", str(SELFTEST), "--model", "pendulum", "--quiet", "--tiers", "structure,kinematics")
    swept = run_cli(*args, "--seeds", "1..2", "--out", str(tmp_path / "sweep"), "--jobs", "2")
    single = run_cli(*args, "--seed", "2", "--out", str(tmp_path / "single"), "--no-record")
    assert (swept.returncode, single.returncode) == (0, 0), swept.stderr + single.stderr
    run = (tmp_path / "sweep" / "latest").resolve()
    summary = json.loads((run / "summary.json").read_text())
    assert (summary["seed"], summary["seeds"]) == (1, [1, 2])
    assert [(m["id"], m["seed"]) for m in summary["models"]] == [("pendulum@seed1", 1), ("pendulum@seed2", 2)]
    for model_id, seed in (("pendulum@seed1", 1), ("pendulum@seed2", 2)):
        assert json.loads((run / "models" / f"{model_id}.json").read_text())["seed"] == seed
        assert (run / f"{model_id}.rrd").stat().st_size > 0
    assert "seeds 1..2;" in (run / "summary.md").read_text()
    (alone,) = json.loads((tmp_path / "single" / "latest" / "summary.json").read_text())["models"]
    assert "seed" not in alone and alone["id"] == "pendulum"  # one seed: the output as without a sweep
    seed1, seed2 = summary["models"]
    assert _kinematics(seed2) == _kinematics(alone)  # the sweep's seed 2 is the run at --seed 2
    assert _kinematics(seed1) != _kinematics(seed2)


@pytest.mark.skipif(importlib.util.find_spec("mani_skill") is not None, reason="ManiSkill is installed here")
@pytest.mark.parametrize("option", [("--tiers", "structure,maniskill"), ("--loader", "maniskill")])
def test_a_missing_extra_is_a_usage_error_naming_it(tmp_path, option):
    """The maniskill tier or loader without ManiSkill installed: exit 2 before anything runs, naming the extra."""
    proc = run_cli(*option, "--model", "pendulum", "--out", str(tmp_path), "--quiet", "--no-record")
    assert proc.returncode == 2 and "needs the maniskill extra: pip install 'mjcf-sapien[maniskill]'" in proc.stderr
    assert not list(tmp_path.iterdir())


def test_old_runs_are_pruned_to_the_newest_kept(tmp_path):
    """A run keeps the newest `keep` run folders: the oldest go, the current one never does, nor a folder named
    by hand or any other file (the names order the runs by their timestamps)."""
    from conformance.runner import prune

    runs = [tmp_path / f"20261127T0{h}0000Z-abcd" for h in range(5)]
    for run in runs:
        (run / "models").mkdir(parents=True)
    (tmp_path / "mine").mkdir()
    (tmp_path / "bench.json").write_text("{}")
    assert prune(tmp_path, 3, runs[-1]) == runs[:2]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([r.name for r in runs[2:]] + ["mine", "bench.json"])
    assert prune(tmp_path, 0, runs[-1]) == [] and prune(tmp_path, 1, runs[2]) == [runs[3]]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([runs[2].name, runs[4].name, "mine", "bench.json"])
