"""`--executor ray` on a cluster that loses a node mid-job: that job is `crashed` with Ray's reason, the run ends
without waiting for it, and the job's process does not outlive its node. A head without CPUs and one worker node,
started by the test on this machine; the node is removed while the self-test's hanging job runs on it."""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

import pytest
from test_conformance_cluster import _job_processes, _processes, _wait_for

from conformance import manifest
from conformance.cluster import ray_missing
from conformance.runner import RunOptions, run

SELFTEST = Path(__file__).resolve().parents[1] / "corpus" / "selftest.toml"


@pytest.mark.skipif(bool(ray_missing()), reason=ray_missing() or "ray is installed")
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds the job's process in /proc")
def test_a_node_lost_mid_job_is_that_jobs_crash(tmp_path, monkeypatch):
    import ray
    from ray.cluster_utils import Cluster

    monkeypatch.setenv("RAY_process_group_cleanup_enabled", "0")  # the harness must not rely on Ray's clean-up
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    try:
        node = cluster.add_node(num_cpus=1)
        ray.init(address=cluster.address, log_to_driver=False)
        entries = manifest.load(SELFTEST).select(["hang"])
        finished = {}
        options = RunOptions(out=tmp_path, tiers=("structure",), progress=False, executor="ray", timeout_scale=100)
        runner = threading.Thread(target=lambda: finished.update(zip(("run_dir", "summary"), run(entries, options))))
        runner.start()
        ((_, job),) = _wait_for(lambda: list(_job_processes().items()), 120, "the job's process")
        cluster.remove_node(node)
        runner.join(timeout=120)
        assert not runner.is_alive(), "the run must not wait for a lost node"
    finally:
        ray.shutdown()
        cluster.shutdown()
    (model,) = finished["summary"]["models"]
    assert model["status"] == "crashed" and model["reason"].startswith("Ray lost the job ("), model
    _wait_for(lambda: job not in set(_processes()), 10, "the job's process to die with its node")
    assert not list(finished["run_dir"].glob(".*")) and not (finished["run_dir"] / "hang.rrd").exists()
    assert os.listdir(finished["run_dir"] / "models") == []
