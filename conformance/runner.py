"""Run every model x seed job through an executor (conformance/executors.py: worker processes here, or a Ray
cluster); a crash or a hang is that job's failure, the run goes on; the summary is rewritten as each job lands."""

from __future__ import annotations

import re
import secrets
import shutil
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from tqdm import tqdm

from . import corpus, executors, summary
from .loaders import DEFAULT as DEFAULT_LOADER
from .loaders import DISTRIBUTIONS, OWN, SKIPS
from .manifest import TIER_NAMES, Expectation, ModelEntry
from .results import ModelResult
from .versions import versions
from .worker import Job


@dataclass
class RunOptions:
    out: Path
    seed: int = 0
    seeds: tuple[int, ...] = ()  # a sweep (more than one): every model once per seed, its id suffixed by the seed
    jobs: int = 0  # 0: all cores
    executor: str = executors.LOCAL  # or ray, ray://HOST:PORT, ray:auto (executors.make)
    tiers: tuple[str, ...] | None = None  # None: the manifest's tiers per model
    tolerance_file: str | None = None
    timeout_scale: float = 1.0
    progress: bool = True
    record: bool = True
    visual_meshes: bool = False  # recordings also draw MuJoCo's visual-only geoms
    run_name: str | None = None
    loader: str = "ours"  # the loader plug-in judged (conformance/loaders.py)
    keep: int = 10  # the newest runs kept in `out` (`prune`); 0: every run
    extra: dict = field(default_factory=dict)


RUN_NAME = re.compile(r"^\d{8}T\d{6}Z-[0-9a-f]{4}$")  # what `new_run_dir` names a run


def prune(out: Path, keep: int, current: Path) -> list[Path]:
    """Delete the oldest runs in `out` beyond the newest `keep` (0: none), never `current`, a run named by hand or
    a folder that is not a run; returns what was deleted
    (tests/test_conformance_runner.py::test_old_runs_are_pruned_to_the_newest_kept)."""
    if keep <= 0:
        return []
    runs = sorted(p for p in out.iterdir() if p.is_dir() and not p.is_symlink() and RUN_NAME.match(p.name))
    doomed = [p for p in runs[: max(0, len(runs) - keep)] if p.resolve() != current.resolve()]
    for run in doomed:
        shutil.rmtree(run, ignore_errors=True)
    return doomed


def new_run_dir(out: Path, name: str | None = None) -> Path:
    """A fresh run folder (never reused, so an earlier run is never touched)."""
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    run = out / (name or f"{stamp}-{secrets.token_hex(2)}")
    run.mkdir(parents=True, exist_ok=False)
    (run / "models").mkdir()
    return run


def sweep(entries: list[ModelEntry], seeds: tuple[int, ...]) -> list[tuple[ModelEntry, int]]:
    """Each entry with the seed it runs at: one seed keeps the entries as they are; a sweep repeats each entry once
    per seed, its id suffixed `@seed<N>` (so its recording and result file are its own); each holds the expectations of
    its seed
    (tests/test_conformance_runner.py::test_a_seed_sweep_runs_each_model_once_per_seed)."""
    if len(seeds) == 1:
        return [(e.at_seed(seeds[0]), seeds[0]) for e in entries]
    return [(replace(e.at_seed(s), id=f"{e.id}@seed{s}"), s) for e in entries for s in seeds]


def foreign(entries: list[ModelEntry], loader: str) -> list[ModelEntry]:
    """The entries as another loader than this project's is judged: the manifest's expected failures describe this
    project's loader, so they are dropped (those tiers are expected to pass); what the model itself decides stays
    (a tier skipped for the model's reason, a load error MuJoCo gives), and the tiers the loader cannot take part
    in are expected skipped (`loaders.SKIPS`). One of this project's loaders keeps every expectation but those
    written for the other (`Expectation.loader`)."""
    if loader in OWN:
        return [
            replace(e, expect={t: x for t, x in e.expect.items() if x.loader in ("", loader)})
            if any(x.loader not in ("", loader) for x in e.expect.values())
            else e
            for e in entries
        ]
    cannot = {t: Expectation(t, "skipped", why) for t, why in SKIPS.get(loader, {}).items()}
    return [
        replace(e, expect={**{t: x for t, x in e.expect.items() if x.outcome in ("skipped", "error")}, **cannot})
        for e in entries
    ]


def run(entries: list[ModelEntry], options: RunOptions) -> tuple[Path, dict]:
    """Run every entry (once per seed of a sweep) through the options' executor; return the run folder and the
    summary document. Writes are atomic throughout."""
    with executors.make(options.executor, options.jobs) as executor:  # a cluster is reached before anything is written
        return _run(entries, options, executor)


def _run(entries: list[ModelEntry], options: RunOptions, executor: executors.Executor) -> tuple[Path, dict]:
    out = Path(options.out)
    out.mkdir(parents=True, exist_ok=True)
    run_dir = new_run_dir(out, options.run_name)
    seeds = tuple(options.seeds) or (options.seed,)
    meta = {
        "run": run_dir.name,
        "seed": seeds[0],
        **({"seeds": list(seeds)} if len(seeds) > 1 else {}),
        "versions": versions(DISTRIBUTIONS.get(options.loader, ())),
        "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        **({"executor": options.executor} if options.executor != executors.LOCAL else {}),
        **({"loader": options.loader} if options.loader != DEFAULT_LOADER else {}),
        **options.extra,
    }
    entries = foreign(entries, options.loader)
    if options.tiers:
        entries = [replace(e, tiers=tuple(options.tiers)) for e in entries]
    tier_names = [t for t in TIER_NAMES if any(t in e.tiers for e in entries)]
    swept = sweep(entries, seeds)
    entries = [e for e, _ in swept]
    seed_of = {e.id: s for e, s in swept} if len(seeds) > 1 else None
    results: dict[str, ModelResult] = {}
    jobs: list[Job] = []
    for entry, seed in swept:
        resolved = corpus.resolve(entry)
        if resolved.path is None:
            results[entry.id] = ModelResult(entry.id, "skipped", reason=resolved.skip_reason)
            continue
        jobs.append(
            Job(
                entry,
                str(resolved.path),
                str(run_dir),
                seed,
                entry.tiers,
                options.tolerance_file,
                options.record,
                options.visual_meshes,
                options.loader,
            )
        )

    def write_summary(interrupted: bool = False) -> dict:
        doc = summary.build({**meta, "interrupted": interrupted, "tiers": tier_names}, entries, results, seed_of)
        summary.atomic_write_json(run_dir / "summary.json", doc)
        summary.atomic_write_text(run_dir / "summary.md", summary.markdown(doc, tier_names))
        return doc

    write_summary()
    bar = tqdm(total=len(entries), initial=len(results), desc="conformance", unit="model", disable=not options.progress)
    interrupted = False
    finished = executor.results(jobs, options.timeout_scale)
    try:
        for job, result in finished:
            results[job.entry.id] = result
            bar.set_postfix_str(f"{job.entry.id}: {summary.headline(result.status, summary.judge(job.entry, result))}")
            bar.update(1)
            write_summary()
    except KeyboardInterrupt:
        interrupted = True
    finally:
        finished.close()  # the executor ends what still runs
        bar.close()
    doc = write_summary(interrupted)
    summary.point_latest(out, run_dir)
    prune(out, options.keep, run_dir)
    if interrupted:
        raise KeyboardInterrupt
    return run_dir, doc
