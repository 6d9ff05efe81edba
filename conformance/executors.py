"""Where the jobs run: every model x seed job is independent, so an executor only has to run each in a fresh process
(PhysX's configuration is process-global) under its timeout and hand back its result, with the job's files
(`models/<id>.json`, `<id>.rrd`) complete in the run folder. The local pool is the default; `ray` sends the jobs to a
Ray cluster (conformance/cluster.py), imported only when asked for."""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Iterable, Iterator
from typing import Protocol

from .collect import collect
from .results import ModelResult
from .worker import Job, main

_POLL_S = 0.05
LOCAL = "local"


class Executor(Protocol):
    """Runs jobs; `results` yields each job with its result as it finishes, in any order. Entering connects (before
    the run writes anything: a cluster that cannot be reached is an error, not a run); leaving lets go of it. A job
    lost (a crash, a timeout, a lost node) is a result like any other, and the rest run on."""

    def __enter__(self): ...

    def __exit__(self, *exc) -> None: ...

    def results(self, jobs: Iterable[Job], timeout_scale: float) -> Iterator[tuple[Job, ModelResult]]: ...


class LocalExecutor:
    """A pool of `workers` spawned processes on this machine, one per job, killed at the job's timeout."""

    def __init__(self, workers: int = 0):
        self.workers = workers or os.cpu_count() or 1

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def results(self, jobs: Iterable[Job], timeout_scale: float) -> Iterator[tuple[Job, ModelResult]]:
        ctx = multiprocessing.get_context("spawn")  # PhysX configuration is process-global: fresh processes
        pending = list(jobs)
        running: dict[str, tuple[Job, multiprocessing.Process, float]] = {}
        try:
            while pending or running:
                while pending and len(running) < self.workers:
                    job = pending.pop(0)
                    proc = ctx.Process(target=main, args=(job,), name=f"conformance-{job.entry.id}", daemon=True)
                    proc.start()
                    running[job.entry.id] = (job, proc, time.monotonic())
                for model_id, (job, proc, start) in list(running.items()):
                    elapsed = time.monotonic() - start
                    timed_out = proc.is_alive() and elapsed > job.entry.timeout_s * timeout_scale
                    if proc.is_alive() and not timed_out:
                        continue
                    if timed_out:
                        proc.kill()
                    proc.join()
                    del running[model_id]
                    yield job, collect(job, proc.exitcode, timed_out, elapsed)
                time.sleep(_POLL_S)
        finally:  # interrupted, or the caller stopped early: no worker outlives the run
            for _, proc, _ in running.values():
                proc.kill()
                proc.join()


def ray_address(spec: str) -> str | None:
    """The address `ray.init` gets for an `--executor` value: `ray` (None: a new local instance), `ray://HOST:PORT`
    (a cluster through Ray Client, as given) or `ray:ADDRESS` (`auto`, or a cluster's HOST:PORT from one of its
    nodes). ValueError for anything else."""
    if spec == "ray":
        return None
    if spec.startswith("ray://") and len(spec) > len("ray://"):
        return spec
    if spec.startswith("ray:") and not spec.startswith("ray:/") and len(spec) > len("ray:"):
        return spec[len("ray:") :]
    raise ValueError(f"unknown executor {spec!r}: use {LOCAL}, ray, ray://HOST:PORT or ray:auto")


def make(spec: str, workers: int = 0) -> Executor:
    """The executor an `--executor` value names; ValueError (before anything runs) for an unknown one or for `ray`
    when Ray is not installed."""
    if spec == LOCAL:
        return LocalExecutor(workers)
    address = ray_address(spec)
    from .cluster import RayExecutor, ray_missing

    missing = ray_missing()
    if missing:
        raise ValueError(f"--executor {spec}: {missing}")
    return RayExecutor(address, workers)
