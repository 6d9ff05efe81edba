"""Evaluate one model inside a worker process: load, run the tiers, write the recording and a result file."""

from __future__ import annotations

import ctypes
import logging
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from . import tolerances as tolerances_mod
from .isolation import ISOLATED_TIERS, isolate
from .loaders import DISTRIBUTIONS
from .manifest import TIER_NAMES, ModelEntry
from .noise import Tally
from .report import TierReport, skipped
from .results import ModelResult
from .summary import atomic_write_json, judge
from .versions import versions

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Job:
    """Everything a worker needs; picklable for a spawned process."""

    entry: ModelEntry
    path: str
    run_dir: str
    seed: int
    tiers: tuple[str, ...]
    tolerance_file: str | None = None
    record: bool = True
    visual_meshes: bool = False  # the recording also draws MuJoCo's visual-only geoms
    loader: str = "ours"  # the loader plug-in judged (conformance/loaders.py)


def result_path(run_dir: str | Path, model_id: str) -> Path:
    return Path(run_dir) / "models" / f"{model_id}.json"


def _inject_fault(fault: str | None) -> None:
    """Harness self-test: fixtures declared with `fault` make the worker die or hang like a broken model."""
    if fault == "crash":
        ctypes.string_at(0)  # a genuine segmentation fault, not a Python exception
    elif fault == "hang":
        while True:
            time.sleep(1.0)


NAN_AFTER_STEPS = 5  # the "nan" fault: SAPIEN's velocities are poisoned after every step past this many


def _poison_steps(result) -> None:
    """Harness self-test (`fault = "nan"`): from the sixth physics step of the worker on, every step leaves NaN
    velocities in every articulation, as a PhysX blow-up would; the next step carries them into the poses."""
    import numpy as np

    step, count = result.scene.step, [0]

    def poisoned() -> None:
        step()
        count[0] += 1
        if count[0] > NAN_AFTER_STEPS:
            for articulation in result.articulations:
                articulation.set_qvel(np.full(articulation.dof, np.nan))

    result.scene.step = poisoned


def judgements(entry: ModelEntry, result: ModelResult) -> dict[str, dict]:
    """Per tier that ran, the summary's judgement and the manifest's expectation, for the recording's verdict."""
    return {
        v.tier: {
            "outcome": v.outcome,
            "expected": v.expected,
            "worse": v.worse,
            "reason": entry.expect[v.tier].reason if v.tier in entry.expect else "",
        }
        for v in judge(entry, result)
        if v.tier in result.tiers
    }


def evaluate(job: Job) -> ModelResult:
    """Run the job in this process and return its result (also used in-process by tests)."""
    from .tiers import TIERS  # heavy imports happen in the worker, not in the parent

    entry = job.entry
    started = time.perf_counter()
    result = ModelResult(
        entry.id,
        "ok",
        source=entry.source,
        path=job.path,
        versions=versions(DISTRIBUTIONS.get(job.loader, ())),
        seed=job.seed,
    )
    _inject_fault(entry.fault)
    tol = tolerances_mod.load(job.tolerance_file).with_overrides(
        entry.tolerances, entry.settings, why=entry.override_reason
    )
    try:
        from .loaders import open_with

        session = open_with(job.loader, job.path)
    except Exception as exc:  # noqa: BLE001 - the loader's failure on this model is this model's failure
        result.status, result.reason = "error", f"load failed: {type(exc).__name__}: {exc}"
        result.traceback, result.seconds = traceback.format_exc(), round(time.perf_counter() - started, 3)
        return result
    if entry.fault == "nan":
        _poison_steps(session.result)
    result.load, result.settings = session.load_info(), session.settings()
    reports: dict[str, TierReport] = {}
    for tier in sorted(job.tiers, key=TIER_NAMES.index):  # contact before dynamics, which disables it
        t0 = time.perf_counter()
        try:
            if tier in session.skips:  # a tier the loader cannot take part in
                report = skipped(tier, session.skips[tier])
            else:
                report = TIERS[tier](session.result, session.model, job.seed, tol)
        except Exception as exc:  # noqa: BLE001 - a tier that raises fails, the others still run
            log.warning("model %s tier %s raised %s", entry.id, tier, exc)
            report = TierReport(
                tier, "fail", notes=[f"tier raised {type(exc).__name__}: {exc}", traceback.format_exc(limit=4)]
            )
        report.settings = {**report.settings, "seconds": round(time.perf_counter() - t0, 3)}
        reports[tier] = report
        result.tiers[tier] = report.to_dict()
        if report.status in ("fail", "diverged") and tier in ISOLATED_TIERS and session.isolates:
            expectation = entry.expect.get(tier)
            claimed = (expectation.passes_without,) if expectation and expectation.passes_without else ()
            t0 = time.perf_counter()
            result.tiers[tier]["isolation"] = isolate(job.path, session.model, tier, job.seed, tol, claimed)
            result.tiers[tier]["settings"]["isolation_seconds"] = round(time.perf_counter() - t0, 3)
    if job.record:
        from .recording import write_recording

        rrd = Path(job.run_dir) / f"{entry.id}.rrd"
        try:
            isolation = {t: r.get("isolation") for t, r in result.tiers.items() if r.get("isolation")}
            write_recording(
                rrd,
                session,
                reports,
                {
                    "model": entry.id,
                    "seed": job.seed,
                    "versions": result.versions,
                    "verdicts": judgements(entry, result),
                    "settings": result.settings,
                    "isolation": isolation,
                },
                visual=job.visual_meshes,
            )
            result.recording = rrd.name
        except Exception as exc:  # noqa: BLE001 - a failed recording is noted, the verdicts stand
            log.warning("model %s: recording failed: %s", entry.id, exc)
            result.recording = None
            result.reason = f"recording failed: {type(exc).__name__}: {exc}"
    result.seconds = round(time.perf_counter() - started, 3)
    return result


def main(job: Job) -> None:
    """Worker process entry point: evaluate and write the result file atomically."""
    logging.basicConfig(level=logging.WARNING)
    with Tally(job.run_dir) as tally:
        result = evaluate(job)
    result.warnings = dict(tally.counts)
    atomic_write_json(result_path(job.run_dir, job.entry.id), result.to_dict())
