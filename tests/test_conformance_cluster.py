"""`--executor ray`: the same jobs on a Ray instance give the summary the local pool gives; a job whose process
crashes or hangs, or whose Ray worker is killed, is that job's failure and the rest complete; the driver writes every
file whole; the default harness never imports Ray. Runs against a local Ray instance this module starts."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from conformance import manifest
from conformance.cluster import ray_missing
from conformance.runner import RunOptions, run

ROOT = Path(__file__).resolve().parents[1]
SELFTEST = ROOT / "corpus" / "selftest.toml"
needs_ray = pytest.mark.skipif(bool(ray_missing()), reason=ray_missing() or "ray is installed")
TIMING = {"seconds", "started", "run", "executor"}  # what two runs of the same jobs may differ in


@pytest.fixture(scope="module")
def ray_instance():
    """A local Ray instance with Ray's own clean-up of a lost worker's processes off: the harness does not rely on
    it (the job's process must die with its task wherever Ray leaves it)."""
    import ray

    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("RAY_process_group_cleanup_enabled", "0")
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def _run(tmp_path: Path, name: str, entries, **options):
    options = {"tiers": None, "jobs": 2, "progress": False, **options}
    return run(entries, RunOptions(out=tmp_path / name, **options))


def _without_timing(doc):
    """The summary without what differs between two runs of the same jobs: timings, the run's name and date."""
    if isinstance(doc, dict):
        return {k: _without_timing(v) for k, v in doc.items() if k not in TIMING and not k.endswith("_seconds")}
    if isinstance(doc, list):
        return [_without_timing(v) for v in doc]
    return doc


@needs_ray
def test_ray_gives_the_local_summary_metric_by_metric(ray_instance, tmp_path):
    entries = manifest.load(ROOT / "corpus" / "manifest.toml").select(["cartpole", "pendulum"])
    _, local = _run(tmp_path, "local", entries, seeds=(0, 1))
    ray_dir, on_ray = _run(tmp_path, "ray", entries, seeds=(0, 1), executor="ray")
    assert on_ray["executor"] == "ray" and "executor" not in local
    assert [m["id"] for m in on_ray["models"]] == [
        "cartpole@seed0",
        "cartpole@seed1",
        "pendulum@seed0",
        "pendulum@seed1",
    ]
    assert {m["status"] for m in on_ray["models"]} == {"ok"}
    for mine, theirs in zip(local["models"], on_ray["models"]):
        assert _without_timing(theirs) == _without_timing(mine), mine["id"]
    assert _without_timing(on_ray) == _without_timing(local)
    for model in on_ray["models"]:  # the driver wrote each job's files from the bytes its task returned
        assert (ray_dir / model["recording"]).stat().st_size > 0
        written = json.loads((ray_dir / "models" / f"{model['id']}.json").read_text())
        assert written["seed"] == model["seed"]
    assert not list(ray_dir.glob(".*")), "no temporary file is left behind"


@needs_ray
def test_a_crash_and_a_hang_on_ray_are_their_jobs_failures_and_the_rest_complete(ray_instance, tmp_path):
    entries = manifest.load(SELFTEST).select(["pendulum", "crash", "hang", "missing"])
    run_dir, summary = _run(tmp_path, "ray", entries, executor="ray", tiers=("structure", "kinematics"))
    models = {m["id"]: m for m in summary["models"]}
    assert models["crash"]["status"] == "crashed" and "SIGSEGV" in models["crash"]["reason"]
    assert models["hang"]["status"] == "timeout" and "3 s timeout" in models["hang"]["reason"]
    assert models["missing"]["status"] == "skipped"
    assert models["pendulum"]["status"] == "ok"
    assert {v["outcome"] for v in models["pendulum"]["verdicts"].values()} == {"pass"}
    assert (run_dir / "pendulum.rrd").stat().st_size > 0 and not (run_dir / "crash.rrd").exists()
    assert sorted(p.name for p in (run_dir / "models").iterdir()) == ["pendulum.json"]
    assert not summary["ok"] and not list(run_dir.glob(".*"))


def _processes() -> dict[int, tuple[int, str]]:
    """Every process: its parent and its command line."""
    found = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            found[int(entry.name)] = (int(stat.rpartition(")")[2].split()[1]), cmdline)
    return found


def _job_processes() -> dict[int, int]:
    """The jobs' own processes on this test's Ray instance, by their Ray worker: spawned processes whose parent is a
    Ray worker (its title: ray::<task>) among this test process's descendants."""
    table = _processes()
    found = {}
    for pid, (parent, cmdline) in table.items():
        if "spawn_main" not in cmdline or not table.get(parent, (0, ""))[1].startswith("ray::"):
            continue
        ancestor = parent
        while ancestor in table and ancestor != os.getpid():
            ancestor = table[ancestor][0]
        if ancestor == os.getpid():
            found[parent] = pid
    return found


def _wait_for(condition, seconds: float, what: str):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        found = condition()
        if found:
            return found
        time.sleep(0.2)
    raise AssertionError(f"waited {seconds:g} s for {what}")


def _landed(out: Path, model_id: str) -> bool:
    """Whether the run writing into `out` has landed that job's result (its summary no longer says pending)."""
    for path in out.glob("*/summary.json"):
        try:
            models = json.loads(path.read_text())["models"]
        except (OSError, ValueError):
            return False
        return any(m["id"] == model_id and m["status"] != "pending" for m in models)
    return False


@needs_ray
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds the worker's processes in /proc")
def test_a_ray_worker_killed_mid_job_is_that_jobs_crash_and_the_run_goes_on(ray_instance, tmp_path):
    entries = manifest.load(SELFTEST).select(["hang", "pendulum"])
    finished = {}
    runner = threading.Thread(
        target=lambda: finished.update(
            zip(
                ("run_dir", "summary"),
                _run(tmp_path, "ray", entries, executor="ray", tiers=("structure",), timeout_scale=100),
            )
        )
    )
    runner.start()
    _wait_for(lambda: _landed(tmp_path / "ray", "pendulum"), 120, "the pendulum's result")
    ((worker, job),) = _wait_for(lambda: list(_job_processes().items()), 60, "the hang's process")
    os.kill(worker, signal.SIGKILL)  # the hang's job runs on; its Ray worker is lost
    runner.join(timeout=120)
    assert not runner.is_alive(), "the run must not wait for a lost worker"
    models = {m["id"]: m for m in finished["summary"]["models"]}
    assert models["hang"]["status"] == "crashed", models["hang"]
    assert models["hang"]["reason"].startswith("Ray lost the job (")
    assert models["pendulum"]["status"] == "ok"
    deadline = time.monotonic() + 10
    while job in _processes() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert job not in set(_processes()), "the job's process dies with its Ray worker"
    assert not (finished["run_dir"] / "hang.rrd").exists() and not list(finished["run_dir"].glob(".*"))


def test_the_default_harness_never_imports_ray(tmp_path):
    code = (
        "import sys; from conformance.cli import main; "
        f"code = main(['run', '--manifest', {str(SELFTEST)!r}, '--model', 'pendulum', '--out', {str(tmp_path)!r},"
        " '--quiet', '--no-record', '--tiers', 'structure']); "
        "import loader, conformance.runner, conformance.worker; "
        "assert 'ray' not in sys.modules, 'ray imported'; sys.exit(code)"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300, check=False
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.skipif(not ray_missing(), reason="ray is installed: its absence cannot be seen here")
def test_without_ray_the_ray_executor_is_a_usage_error_naming_the_extra(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "conformance", "run", "--executor", "ray", "--out", str(tmp_path / "out")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2 and "pip install 'mjcf-sapien[ray]'" in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists()
