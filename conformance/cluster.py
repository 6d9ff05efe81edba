"""Jobs on a Ray cluster (`--executor ray`, `ray://HOST:PORT`, `ray:auto`): one Ray task per model x seed job.

On the node the task runs the job as the local pool does, in a fresh spawned process under the job's timeout (so the
timeout counts the job, not its wait in Ray's queue, and a crash or a hang is that job's result), in a folder of its
own; it returns the result with the bytes of its files. The driver writes them into the run folder atomically, so a
job lost half-way leaves nothing half-written. A task Ray loses (its worker killed, its node gone, the task raised)
is that job's `crashed` result, with Ray's reason; the run goes on. No task is retried: a lost job is reported.

The nodes need the project and its extras installed, as on the driver; a model a node cannot find is `crashed`.
Tests: tests/test_conformance_cluster.py."""

from __future__ import annotations

import ctypes
import logging
import multiprocessing
import os
import signal
import socket
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

from .collect import collect
from .corpus import resolve
from .noise import MUJOCO_LOG
from .results import ModelResult
from .summary import atomic_write_bytes
from .worker import Job, main, result_path

_WAIT_S = 0.5  # the driver wakes this often (an interrupt is seen)
_PR_SET_PDEATHSIG = 1


def ray_missing() -> str:
    """Why Ray cannot be used here, or '' when it can."""
    try:
        import ray  # noqa: F401
    except ImportError as exc:
        return f"Ray is not installed ({exc}); install the extra: pip install 'mjcf-sapien[ray]'"
    return ""


@dataclass(frozen=True)
class NodeResult:
    """What a task sends back: the result, and the bytes of the files the job wrote (None: it wrote none)."""

    result: dict  # ModelResult.to_dict()
    result_file: bytes | None
    recording: bytes | None
    mujoco_log: bytes


def _die_with_parent(parent: int) -> None:
    """On Linux, the job's process is killed with the task's (a cancelled task, a killed worker): no orphan hangs on."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:  # the task died before the line above
            os.kill(os.getpid(), signal.SIGKILL)


def _child(job: Job, parent: int) -> None:
    _die_with_parent(parent)
    main(job)


def _read(path: Path) -> bytes | None:
    return path.read_bytes() if path.is_file() else None


def run_on_node(job: Job, timeout_s: float) -> NodeResult:
    """The Ray task: the job in a fresh process in a folder of its own, under `timeout_s`; its result and files."""
    resolved = resolve(job.entry)  # the node's own copy of the model
    if resolved.path is None:
        lost = ModelResult(
            job.entry.id, "crashed", reason=f"node {socket.gethostname()} cannot find the model: {resolved.skip_reason}"
        )
        return NodeResult(lost.to_dict(), None, None, b"")
    with tempfile.TemporaryDirectory(prefix="conformance-job-") as tmp:
        local = replace(job, path=str(resolved.path), run_dir=tmp)
        (Path(tmp) / "models").mkdir()
        proc = multiprocessing.get_context("spawn").Process(target=_child, args=(local, os.getpid()), daemon=True)
        start = time.monotonic()
        proc.start()
        proc.join(timeout_s)
        timed_out = proc.is_alive()
        if timed_out:
            proc.kill()
            proc.join()
        result = collect(local, proc.exitcode, timed_out, time.monotonic() - start)
        recording = _read(Path(tmp) / result.recording) if result.recording else None
        return NodeResult(
            result.to_dict(), _read(result_path(tmp, job.entry.id)), recording, _read(Path(tmp) / MUJOCO_LOG) or b""
        )


def _lost(job: Job, exc: Exception) -> ModelResult:
    """A job Ray could not finish: its reason, Ray's words (the task's own exception where it raised one)."""
    cause = getattr(exc, "cause", None)
    if isinstance(cause, BaseException):
        why = f"the task raised {type(cause).__name__}: {cause}"
    else:
        lines = str(exc).strip().splitlines()
        why = f"{type(exc).__name__}: {lines[0] if lines else ''}"
    return ModelResult(job.entry.id, "crashed", reason=f"Ray lost the job ({why})")


class RayExecutor:
    """Sends every job to Ray as one task (one CPU each) and lands the results on the driver as they finish. It joins
    the Ray instance this process is already connected to, else connects to `address` (None: starts a local instance
    with `workers` CPUs, all when 0) and disconnects at the end."""

    def __init__(self, address: str | None, workers: int = 0):
        self.address, self.workers = address, workers
        self._connected_here = False
        self._task = None

    def __enter__(self):
        import ray

        if not ray.is_initialized():
            options = {"logging_level": logging.WARNING, "log_to_driver": False}
            if self.address is None:
                options.update(include_dashboard=False, num_cpus=self.workers or None)
            try:
                ray.init(address=self.address, **options)
            except ConnectionError as exc:  # before the run writes anything: a usage error
                raise ValueError(f"cannot reach the Ray cluster at {self.address}: {exc}") from exc
            self._connected_here = True
        self._task = ray.remote(run_on_node).options(num_cpus=1, max_retries=0)
        return self

    def __exit__(self, *exc) -> None:
        import ray

        if self._connected_here:
            ray.shutdown()
            self._connected_here = False

    def results(self, jobs: Iterable[Job], timeout_scale: float) -> Iterator[tuple[Job, ModelResult]]:
        import ray

        running = {self._task.remote(job, job.entry.timeout_s * timeout_scale): job for job in jobs}
        try:
            while running:
                ready, _ = ray.wait(list(running), num_returns=1, timeout=_WAIT_S)
                for ref in ready:
                    job = running.pop(ref)
                    try:
                        landed = self._land(job, ray.get(ref))
                    except ray.exceptions.RayError as exc:
                        landed = _lost(job, exc)
                    yield job, landed
        finally:  # interrupted, or the caller stopped early: cancel what is left (its processes die with it)
            for ref in running if ray.is_initialized() else ():
                ray.cancel(ref, force=True)

    @staticmethod
    def _land(job: Job, node: NodeResult) -> ModelResult:
        """The task's files into the run folder, each written whole: the recording before the result naming it."""
        result = ModelResult.from_dict(node.result)
        run_dir = Path(job.run_dir)
        if node.recording is not None and result.recording:
            atomic_write_bytes(run_dir / result.recording, node.recording)
        if node.result_file is not None:
            atomic_write_bytes(result_path(run_dir, job.entry.id), node.result_file)
        if node.mujoco_log:
            with open(run_dir / MUJOCO_LOG, "ab") as log:  # appended in one write, as a local worker appends
                log.write(node.mujoco_log)
        return result
