"""Run models in worker processes with timeouts; a crash or a hang is that model's failure, the run goes on."""

from __future__ import annotations

import json
import multiprocessing
import os
import secrets
import signal
import time
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from tqdm import tqdm

from . import corpus, summary
from .manifest import TIER_NAMES, ModelEntry
from .results import ModelResult
from .versions import versions
from .worker import Job, main, result_path

_POLL_S = 0.05


@dataclass
class RunOptions:
    out: Path
    seed: int = 0
    jobs: int = 0  # 0: all cores
    tiers: tuple[str, ...] | None = None  # None: the manifest's tiers per model
    tolerance_file: str | None = None
    timeout_scale: float = 1.0
    progress: bool = True
    record: bool = True
    visual_meshes: bool = False  # recordings also draw MuJoCo's visual-only geoms
    run_name: str | None = None
    extra: dict = field(default_factory=dict)


def new_run_dir(out: Path, name: str | None = None) -> Path:
    """A fresh run folder (never reused, so an earlier run is never touched)."""
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    run = out / (name or f"{stamp}-{secrets.token_hex(2)}")
    run.mkdir(parents=True, exist_ok=False)
    (run / "models").mkdir()
    return run


def _describe_exit(code: int | None) -> str:
    if code is None:
        return "no exit code"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _collect(job: Job, exitcode: int | None, timed_out: bool, seconds: float) -> ModelResult:
    partial = Path(job.run_dir) / f".{job.entry.id}.rrd.partial"  # a recording the worker did not finish
    partial.unlink(missing_ok=True)
    if timed_out:
        return ModelResult(job.entry.id, "timeout", seconds=round(seconds, 3),
                           reason=f"worker exceeded its {job.entry.timeout_s:g} s timeout and was killed")
    path = result_path(job.run_dir, job.entry.id)
    if path.is_file():
        try:
            return ModelResult.from_dict(json.loads(path.read_text()))
        except (json.JSONDecodeError, TypeError, ValueError) as exc:
            return ModelResult(job.entry.id, "crashed", reason=f"unreadable result file: {exc}")
    return ModelResult(job.entry.id, "crashed", seconds=round(seconds, 3),
                       reason=f"worker died without a result ({_describe_exit(exitcode)})")


def run(entries: list[ModelEntry], options: RunOptions) -> tuple[Path, dict]:
    """Run every entry; return the run folder and the summary document. Writes are atomic throughout."""
    out = Path(options.out)
    out.mkdir(parents=True, exist_ok=True)
    run_dir = new_run_dir(out, options.run_name)
    meta = {"run": run_dir.name, "seed": options.seed, "versions": versions(),
            "started": datetime.now(timezone.utc).isoformat(timespec="seconds"), **options.extra}
    if options.tiers:
        entries = [replace(e, tiers=tuple(options.tiers)) for e in entries]
    tier_names = [t for t in TIER_NAMES if any(t in e.tiers for e in entries)]
    results: dict[str, ModelResult] = {}
    jobs: list[Job] = []
    for entry in entries:
        resolved = corpus.resolve(entry)
        if resolved.path is None:
            results[entry.id] = ModelResult(entry.id, "skipped", reason=resolved.skip_reason)
            continue
        jobs.append(Job(entry, str(resolved.path), str(run_dir), options.seed, entry.tiers,
                        options.tolerance_file, options.record, options.visual_meshes))

    def write_summary(interrupted: bool = False) -> dict:
        doc = summary.build({**meta, "interrupted": interrupted, "tiers": tier_names}, entries, results)
        summary.atomic_write_json(run_dir / "summary.json", doc)
        summary.atomic_write_text(run_dir / "summary.md", summary.markdown(doc, tier_names))
        return doc

    write_summary()
    ctx = multiprocessing.get_context("spawn")  # PhysX configuration is process-global: fresh processes
    n_workers = options.jobs or os.cpu_count() or 1
    pending = list(jobs)
    running: dict[str, tuple[Job, multiprocessing.Process, float]] = {}
    bar = tqdm(total=len(entries), initial=len(results), desc="conformance", unit="model",
               disable=not options.progress)
    interrupted = False
    try:
        while pending or running:
            while pending and len(running) < n_workers:
                job = pending.pop(0)
                proc = ctx.Process(target=main, args=(job,), name=f"conformance-{job.entry.id}", daemon=True)
                proc.start()
                running[job.entry.id] = (job, proc, time.monotonic())
            for model_id, (job, proc, start) in list(running.items()):
                elapsed = time.monotonic() - start
                timed_out = proc.is_alive() and elapsed > job.entry.timeout_s * options.timeout_scale
                if proc.is_alive() and not timed_out:
                    continue
                if timed_out:
                    proc.kill()
                proc.join()
                results[model_id] = _collect(job, proc.exitcode, timed_out, elapsed)
                del running[model_id]
                result = results[model_id]
                bar.set_postfix_str(f"{model_id}: {summary.headline(result.status, summary.judge(job.entry, result))}")
                bar.update(1)
                write_summary()
            time.sleep(_POLL_S)
    except KeyboardInterrupt:
        interrupted = True
        for _, proc, _ in running.values():
            proc.kill()
            proc.join()
    finally:
        bar.close()
    doc = write_summary(interrupted)
    summary.point_latest(out, run_dir)
    if interrupted:
        raise KeyboardInterrupt
    return run_dir, doc
