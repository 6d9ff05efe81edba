"""The robustness session: mutations, the outcome classifier (each bad outcome produced by a deliberate mistake),
a bounded derandomized profile over the default corpus, and the saved bad mutants replayed."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from support.corpus import suite_path

import conformance.session
from conformance import manifest
from conformance.robustness import mutations
from conformance.robustness.outcome import BAD, GOOD, start
from conformance.robustness.session import Workspace, registered, replay, run, sources_of

ROOT = Path(__file__).resolve().parent.parent
MUTANTS = ROOT / "corpus" / "regressions" / "mutants"
PROFILE_MUTANTS = 300  # the bounded profile that runs with the tests; `nox -s robustness` runs any number


def _write(workspace: Workspace, source: Path, data: bytes, name: str = "t") -> str:
    return str(workspace.write(source, data, name))


@pytest.fixture
def workspace():
    space = Workspace()
    yield space
    space.close()


@pytest.mark.parametrize("kind", sorted(mutations.WEIGHTS))
def test_every_kind_is_reproducible_changes_the_document_and_ends_well(kind, workspace):
    """The same (seed, index) gives the same bytes; every kind changes the document; and the loader's outcome on
    it, judged in a child process with MuJoCo as the oracle, is a good one."""
    source = suite_path("cartpole")
    data = source.read_bytes()
    first, again = mutations.mutate(data, 3, 7, kind), mutations.mutate(data, 3, 7, kind)
    assert first == again and first.data != data and first.kind == kind
    outcome = start(_write(workspace, source, first.data), 0, 240.0).join()
    assert outcome.outcome in GOOD, (first.description, outcome)


def _patched_loader(monkeypatch, make):
    """The loader the classifier calls, replaced by `make(path)` (forked children inherit the patch)."""
    real = conformance.session.quiet_load
    monkeypatch.setattr(conformance.session, "quiet_load", lambda path, fix_root_link=True: make(real, path))


def _raise(real, path):
    raise ZeroDivisionError("a loader bug")


def _moved_body(real, path):
    text = (
        Path(path)
        .read_text()
        .replace('<body name="pole_1" childclass="pole">', '<body name="pole_1" childclass="pole" pos="0 0 .05">')
    )
    assert text != Path(path).read_text()
    moved = Path(path).with_name(".moved.xml")
    moved.write_text(text)
    return real(moved)


def _velocities_after_each_step(value: float):
    """A loader whose articulation's velocities are set to `value` after every `step` (a state running off)."""

    def mistake(real, path):
        result = real(path)
        step = result.step

        def set_after(*args, **kwargs):
            step(*args, **kwargs)
            art = result.articulations[0]
            art.set_qvel(np.full(art.dof, value, dtype=np.float32))

        result.step = set_after
        return result

    return mistake


_diverging, _gone_nan = _velocities_after_each_step(1e6), _velocities_after_each_step(np.nan)


@pytest.mark.parametrize(
    "mistake, expected",
    [(_raise, "untyped_error"), (_moved_body, "silently_wrong"), (_diverging, "divergence"), (_gone_nan, "divergence")],
)
def test_a_deliberate_mistake_is_a_bad_outcome(mistake, expected, monkeypatch, workspace):
    """A loader that raises an untyped error, one that moves a body 5 cm, one whose state runs off, one whose state
    goes NaN (the next `step` refuses it: DivergenceError): each is the bad outcome it is; the real loader on the
    same document is `loaded_right`."""
    source = suite_path("cartpole")
    path = _write(workspace, source, source.read_bytes())
    assert start(path).join().outcome == "loaded_right"
    _patched_loader(monkeypatch, mistake)
    assert start(path).join().outcome == expected


def test_loading_what_mujoco_rejects_is_silently_wrong(monkeypatch, workspace):
    source = suite_path("cartpole")
    truncated = _write(workspace, source, source.read_bytes()[:200])
    assert start(truncated).join().outcome == "typed_error"
    _patched_loader(monkeypatch, lambda real, path: real(source))
    assert start(truncated).join().outcome == "silently_wrong"


def _segfault(path, seed, conn):
    import faulthandler

    faulthandler.disable()  # the dying child's fault report is not the test's output
    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    os.kill(os.getpid(), signal.SIGSEGV)


def _sleep(path, seed, conn):
    time.sleep(60)


def _spin(path, seed, conn):
    while True:
        pass


def test_a_dead_child_is_a_crash_and_a_slow_one_a_hang(workspace):
    """A child that dies is a crash; one that spins past its timeout of CPU time, or sits blocked past
    WALL_FACTOR times it, is a hang (a child merely slowed by a busy machine is neither)."""
    from conformance.robustness.outcome import WALL_FACTOR

    source = suite_path("cartpole")
    path = _write(workspace, source, source.read_bytes())
    assert start(path, target=_segfault).join().outcome == "crash"
    began = time.monotonic()
    spun = start(path, timeout=1.0, target=_spin).join()
    assert spun.outcome == "hang" and "CPU time" in spun.detail, spun
    blocked = start(path, timeout=1.0, target=_sleep).join()
    assert blocked.outcome == "hang" and "CPU" not in blocked.detail, blocked
    assert time.monotonic() - began < 2 * WALL_FACTOR + 10.0


def _sources():
    return sources_of(manifest.load(ROOT / "corpus" / "manifest.toml").models)


def test_a_bounded_profile_of_the_default_corpus_has_no_bad_outcome():
    """`PROFILE_MUTANTS` mutants under seed 0 (the session's derandomized profile): no crash, hang, untyped error,
    silently wrong load or divergence MuJoCo does not share; most kinds are drawn."""
    tally = run(_sources(), PROFILE_MUTANTS, seed=0, jobs=os.cpu_count() or 1)
    assert tally.total == PROFILE_MUTANTS
    assert tally.bad == 0, [f.to_dict() for f in tally.findings]
    assert len(tally.by_kind) >= 9 and set(tally.outcomes) <= set(GOOD) | set(BAD)


SAVED = registered(MUTANTS)


def _saved(name: str):
    """A saved mutant as a test case: a known bug (its `known` reason) is a strict xfail until it ends well."""
    known = SAVED[name].get("known")
    return pytest.param(name, marks=[pytest.mark.xfail(strict=True, reason=known)] if known else [])


@pytest.mark.parametrize("name", [_saved(name) for name in sorted(SAVED)])
def test_a_saved_bad_mutant_now_ends_well(name):
    """Every bad mutant a session found and saved (its source and what it did in corpus/regressions/mutants/
    mutants.toml) is replayed beside its source's files, under the seed it was found with (`seed`, default 0);
    today's outcome is a good one."""
    entry = SAVED[name]
    paths = {s.source: s.path for s in _sources()}
    if entry["source"] not in paths:
        pytest.skip(f"{entry['source']} is not installed")
    outcome = replay(MUTANTS, name, paths[entry["source"]], seed=entry.get("seed", 0))
    assert outcome.outcome in GOOD, (entry["found"], outcome)


def test_saved_mutants_are_registered():
    files = {p.name for p in MUTANTS.glob("*.xml")}
    assert files and files == set(SAVED)


def test_an_interrupted_run_reports_the_mutants_it_judged():
    """Ctrl-C during a run: the running children are stopped and the tally of what was judged comes back, marked
    interrupted (the CLI writes it and exits 1)."""

    def interrupt(tally):
        raise KeyboardInterrupt

    tally = run(_sources()[:1], 50, seed=0, jobs=1, progress=interrupt)
    assert tally.interrupted and tally.total == 1 and tally.to_dict()["interrupted"]


def test_progress_names_a_bad_mutant_when_it_is_found(capsys):
    from conformance.robustness.mutations import Mutant
    from conformance.robustness.outcome import Outcome
    from conformance.robustness.session import Tally, print_progress

    show, tally = print_progress(1000), Tally()
    tally.add(Mutant("numeric_value", "body mass = nan", b""), Outcome("crash", "process", "exit -11"), "src", 7)
    show(tally)
    show(tally)
    err = capsys.readouterr().err
    assert err.count("bad: crash src #7 numeric_value (body mass = nan): exit -11") == 1, err
