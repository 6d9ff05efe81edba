"""A finished worker's result: the result file it wrote, or why it wrote none (a crash, its timeout). Both executors
(conformance/executors.py, conformance/cluster.py) run a job in a fresh child process and judge its end here."""

from __future__ import annotations

import json
import signal
from pathlib import Path

from .results import ModelResult
from .worker import Job, result_path


def describe_exit(code: int | None) -> str:
    if code is None:
        return "no exit code"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def collect(job: Job, exitcode: int | None, timed_out: bool, seconds: float) -> ModelResult:
    """The job's result once its process is gone: a timeout, the result file, or a crash (no result file)."""
    partial = Path(job.run_dir) / f".{job.entry.id}.rrd.partial"  # a recording the worker did not finish
    partial.unlink(missing_ok=True)
    if timed_out:
        return ModelResult(
            job.entry.id,
            "timeout",
            seconds=round(seconds, 3),
            reason=f"worker exceeded its {job.entry.timeout_s:g} s timeout and was killed",
        )
    path = result_path(job.run_dir, job.entry.id)
    if path.is_file():
        try:
            return ModelResult.from_dict(json.loads(path.read_text()))
        except (json.JSONDecodeError, TypeError, ValueError) as exc:
            return ModelResult(job.entry.id, "crashed", reason=f"unreadable result file: {exc}")
    return ModelResult(
        job.entry.id,
        "crashed",
        seconds=round(seconds, 3),
        reason=f"worker died without a result ({describe_exit(exitcode)})",
    )
