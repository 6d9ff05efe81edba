"""The robustness session: mutants of the corpus's real files, each loaded and stepped in its own process.

`run(sources, mutants, seed)` spreads `mutants` over the source files round-robin, runs up to `jobs` children at
once (`outcome.start`), and returns the counts by outcome and kind, the throughput and every bad mutant, shrunk
and saved to `corpus/regressions/mutants/` when `save` is given (the test suite replays them, `replay`).
A mutant is written into a fresh folder that links every file beside its source, so its meshes and includes
resolve as the source's do. Tested by tests/test_robustness.py."""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass, field
from multiprocessing.connection import wait
from pathlib import Path

import tomllib

from .mutations import Mutant, mutate
from .outcome import BAD, Outcome, Running, start

TIMEOUT_S = 60.0  # CPU seconds per mutant (outcome.Running); a 10,000-body model loads in about 15 s
HUGE_TIMEOUT_S = 240.0
SHRINK_TRIES = 60
REGISTRY = "mutants.toml"


@dataclass(frozen=True)
class Source:
    """A real document the mutants start from: its manifest source string (how a replay finds it) and its file."""

    source: str
    path: Path


@dataclass
class Finding:
    source: str
    index: int
    kind: str
    description: str
    outcome: Outcome
    saved: str = ""

    def to_dict(self) -> dict:
        return {
            "source": self.source,
            "index": self.index,
            "kind": self.kind,
            "description": self.description,
            **self.outcome.to_dict(),
            "saved": self.saved,
        }


@dataclass
class Tally:
    outcomes: Counter = field(default_factory=Counter)
    by_kind: dict[str, Counter] = field(default_factory=dict)
    findings: list[Finding] = field(default_factory=list)
    seconds: float = 0.0
    interrupted: bool = False  # stopped by Ctrl-C before every mutant was judged

    def add(self, mutant: Mutant, outcome: Outcome, source: str, index: int) -> None:
        self.outcomes[outcome.outcome] += 1
        self.by_kind.setdefault(mutant.kind, Counter())[outcome.outcome] += 1
        if outcome.bad:
            self.findings.append(Finding(source, index, mutant.kind, mutant.description, outcome))

    @property
    def total(self) -> int:
        return sum(self.outcomes.values())

    @property
    def bad(self) -> int:
        return sum(self.outcomes[b] for b in BAD)

    def to_dict(self) -> dict:
        return {
            "mutants": self.total,
            "interrupted": self.interrupted,
            "seconds": round(self.seconds, 1),
            "mutants_per_second": round(self.total / self.seconds, 2) if self.seconds else None,
            "bad": self.bad,
            "outcomes": dict(sorted(self.outcomes.items())),
            "by_kind": {k: dict(sorted(v.items())) for k, v in sorted(self.by_kind.items())},
            "findings": [f.to_dict() for f in self.findings],
        }


class Workspace:
    """Folders beside each source's files, where mutants are written and removed again."""

    def __init__(self) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="mutants-"))
        self.folders: dict[Path, Path] = {}

    def write(self, source: Path, data: bytes, name: str) -> Path:
        folder = self.folders.get(source.parent)
        if folder is None:
            folder = self.root / f"s{len(self.folders)}"
            folder.mkdir()
            for entry in source.parent.iterdir():
                (folder / entry.name).symlink_to(entry)
            self.folders[source.parent] = folder
        path = folder / f".{name}.mutant.xml"
        path.write_bytes(data)
        return path

    def close(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


def sources_of(entries) -> list[Source]:
    """The installed files of manifest entries (a source not installed is left out)."""
    from ..corpus import resolve

    found = []
    for entry in entries:
        path = resolve(entry).path
        if path is not None and path.is_file():
            found.append(Source(entry.source, path))
    return found


def timeout_for(mutant: Mutant) -> float:
    return HUGE_TIMEOUT_S if mutant.kind == "huge_model" else TIMEOUT_S


def run(
    sources: list[Source], mutants: int, seed: int = 0, jobs: int = 2, save: Path | None = None, progress=None
) -> Tally:
    """Mutants 0..mutants-1 under `seed`, source i % len(sources); bad ones shrunk and saved into `save`."""
    tally = Tally()
    workspace = Workspace()
    data = {s.path: s.path.read_bytes() for s in sources}
    pending = list(range(mutants))[::-1]
    running: list[tuple[Running, Mutant, Source, int]] = []
    started = time.perf_counter()
    try:
        while pending or running:
            try:
                running = _advance(running, pending, jobs, sources, data, seed, workspace, tally, progress)
            except KeyboardInterrupt:  # Ctrl-C: the mutants judged so far are reported, nothing is lost
                for item in running:
                    item[0].close()
                tally.interrupted = True
                break
        tally.seconds = time.perf_counter() - started
        if save is not None:
            for finding in tally.findings:
                source = next(s for s in sources if s.source == finding.source)
                mutant = mutate(data[source.path], seed, finding.index)
                shrunk = (
                    mutant.data
                    if tally.interrupted
                    else shrink(source.path, mutant, finding.outcome, seed + finding.index, workspace)
                )
                finding.saved = record(save, finding, source, shrunk, seed)
    finally:
        workspace.close()
    return tally


def _advance(
    running: list,
    pending: list[int],
    jobs: int,
    sources: list[Source],
    data: dict,
    seed: int,
    workspace: Workspace,
    tally: Tally,
    progress,
) -> list:
    """Start mutants up to `jobs` at once, wait for one to end, tally what ended; the ones still running."""
    while pending and len(running) < jobs:
        index = pending.pop()
        source = sources[index % len(sources)]
        mutant = mutate(data[source.path], seed, index)
        path = workspace.write(source.path, mutant.data, f"m{index}")
        running.append((start(str(path), seed + index, timeout_for(mutant)), mutant, source, index))
    wait([r.receive for r, *_ in running], timeout=min(r.left() for r, *_ in running))
    still = []
    for item in running:
        outcome = item[0].finish()
        if outcome is None:
            still.append(item)
            continue
        _, mutant, source, index = item
        tally.add(mutant, outcome, source.source, index)
        if progress:
            progress(tally)
    return still


def shrink(
    source: Path, mutant: Mutant, outcome: Outcome, seed: int, workspace: Workspace, tries: int = SHRINK_TRIES
) -> bytes:
    """The mutant with as many elements removed as keep its bad outcome (greedy, at most `tries` runs)."""
    try:
        root = ET.fromstring(mutant.data)
    except ET.ParseError:
        return mutant.data
    best = mutant.data
    candidates = [(parent, child) for parent in root.iter() for child in list(parent)]
    for parent, child in candidates[::-1]:
        if tries <= 0:
            break
        if child not in list(parent):
            continue
        at = list(parent).index(child)
        parent.remove(child)
        trial = ET.tostring(root)
        tries -= 1
        path = workspace.write(source, trial, "shrink")
        got = start(str(path), seed, timeout_for(mutant)).join()
        if got.outcome == outcome.outcome:
            best = trial
        else:
            parent.insert(at, child)
    return best


def record(folder: Path, finding: Finding, source: Source, data: bytes, seed: int) -> str:
    """Write a bad mutant into `folder` and add it to the folder's registry (source, kind, what it did)."""
    folder.mkdir(parents=True, exist_ok=True)
    stem = Path(source.source.rpartition(":")[2]).stem.replace("/", "_")
    name = f"{stem}-{finding.kind}-{seed}-{finding.index}.xml"
    (folder / name).write_bytes(data)
    registry = folder / REGISTRY
    with registry.open("a") as out:
        out.write(
            f'\n[mutant."{name}"]\nsource = {json.dumps(source.source)}\nkind = {json.dumps(finding.kind)}\n'
            f"found = {json.dumps(finding.outcome.outcome + ': ' + finding.outcome.detail[:200])}\n"
            f"description = {json.dumps(finding.description[:200])}\n"
        )
    return name


def registered(folder: Path) -> dict[str, dict]:
    """The saved mutants of `folder`: file name -> {source, kind, found, description}, and where a session added
    them, `seed` (the seed it replays under; default 0) and `known` (a known bug's reason: its replay is expected to
    stay bad)."""
    registry = folder / REGISTRY
    if not registry.is_file():
        return {}
    return tomllib.loads(registry.read_text()).get("mutant", {})


def replay(folder: Path, name: str, path: Path, seed: int = 0) -> Outcome:
    """A saved mutant's outcome today, run beside its source's files (`path`) as in the session."""
    workspace = Workspace()
    try:
        mutant = workspace.write(path, (folder / name).read_bytes(), "replay")
        return start(str(mutant), seed, HUGE_TIMEOUT_S).join()
    finally:
        workspace.close()


def print_progress(total: int):
    """A progress line every 5 % of `total`, and each bad mutant the moment it is found (source, index, kind,
    what it did), so a long run shows what it found before it ends."""
    step = max(1, total // 20)
    shown = 0

    def show(tally: Tally) -> None:
        nonlocal shown
        for finding in tally.findings[shown:]:
            print(
                f"robustness: bad: {finding.outcome.outcome} {finding.source} #{finding.index} {finding.kind} "
                f"({finding.description}): {finding.outcome.detail[:200]}",
                file=sys.stderr,
                flush=True,
            )
        shown = len(tally.findings)
        if tally.total % step == 0 or tally.total == total:
            print(f"robustness: {tally.total}/{total} mutants, bad {tally.bad}", file=sys.stderr, flush=True)

    return show
