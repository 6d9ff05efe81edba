"""The properties as hypothesis tests, their profiles, and the `fuzz` command.

Profiles: "ci" is derandomized and bounded (inside the normal test suite); "fuzz" draws many examples and keeps
hypothesis's example database between runs (`.hypothesis/fragments`), so failures found once are replayed
first next time. The fuzz command deals every property's examples out over worker processes (`--workers`, default
2), each with its own random seed: they share the example database (hypothesis writes it atomically) and save
shrunk counterexamples under a hash of their content, so two workers never clobber each other's files.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import os
import resource
import time
import traceback
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis.database import DirectoryBasedExampleDatabase

from .corner_cases import CORNER_CASES
from .document import RawDocument
from .properties import STATIC_TIERS, assert_conforms
from .robot_classes import robot_classes
from .strategies import broken_documents, documents, kinematic_trees
from .tally import Tally

log = logging.getLogger(__name__)
DATABASE = Path(".hypothesis") / "fragments"
CI_EXAMPLES = {"conformance": 300, "error_parity": 100, "kinematics": 150, "robot_classes": 60}
SHARES = {"conformance": 3, "error_parity": 1, "kinematics": 1, "robot_classes": 1}  # how `--examples N` is split
_HEALTH = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]


def ci_settings(examples: int) -> settings:
    return settings(
        max_examples=examples,
        derandomize=True,
        database=None,
        deadline=None,
        suppress_health_check=_HEALTH,
        print_blob=False,
    )


def fuzz_settings(examples: int, database: Path = DATABASE) -> settings:
    return settings(
        max_examples=examples,
        database=DirectoryBasedExampleDatabase(str(database)),
        deadline=None,
        suppress_health_check=_HEALTH,
        print_blob=True,
    )


def mutation_settings(examples: int) -> settings:
    """For mutation tests: stop at the first failure (no shrinking, one bug reported)."""
    return settings(ci_settings(examples), phases=[Phase.explicit, Phase.generate], report_multiple_bugs=False)


def conformance_property(document, tally: Tally) -> None:
    """Compiles in MuJoCo -> loads and passes the tiers, actuators map to MuJoCo's gains; else error parity."""
    assert_conforms(document, property_name="conformance", tally=tally)


def error_parity_property(document, tally: Tally) -> None:
    """A document with a mistake MuJoCo rejects: the loader raises MJCFError with MuJoCo's message."""
    assert_conforms(document, property_name="error_parity", tally=tally)


def kinematics_property(document, tally: Tally) -> None:
    """Random orientations and joint axes: structure and forward kinematics agree with MuJoCo."""
    assert_conforms(
        document,
        tiers=("structure", "kinematics"),
        dynamics=False,
        actuators=False,
        property_name="kinematics",
        tally=tally,
    )


def robot_classes_property(document, tally: Tally) -> None:
    """Past-the-end starts, URDF-style frictionloss, many limits at once, tiny and zero inertias, coupled fingers:
    every tier, the contact-free dynamic ones included, agrees with MuJoCo."""
    assert_conforms(document, property_name="robot_classes", tally=tally)


PROPERTIES: dict[str, tuple[Callable, Callable]] = {
    "conformance": (documents, conformance_property),
    "error_parity": (broken_documents, error_parity_property),
    "kinematics": (kinematic_trees, kinematics_property),
    "robot_classes": (robot_classes, robot_classes_property),
}


def corner_examples(error: bool) -> list[RawDocument]:
    """The corner-case rows MuJoCo accepts (error=False) or rejects (error=True) on the installed version."""
    return [case.document for case in CORNER_CASES if (case.expect is None) == error]


def hypothesis_test(
    name: str, profile: settings, with_examples: bool = True, tally: Tally | None = None
) -> Callable[[], None]:
    """The named property as a runnable hypothesis test under `profile`, seeded with the corner cases; what it
    exercises is counted in `tally` (None: not counted)."""
    strategy, prop = PROPERTIES[name]
    tally = Tally() if tally is None else tally

    def test(document) -> None:
        prop(document, tally)

    test.__name__ = f"{name}_property"
    test = given(strategy())(test)
    if with_examples and name in ("conformance", "error_parity"):
        for document in corner_examples(error=name == "error_parity"):
            test = example(document)(test)
    return settings(profile)(test)


def split(examples: int, names: list[str]) -> dict[str, int]:
    """`examples` in total, shared among the properties by SHARES (each gets at least one)."""
    total = sum(SHARES[n] for n in names)
    return {n: max(1, round(examples * SHARES[n] / total)) for n in names}


def divide(shares: dict[str, int], workers: int) -> list[dict[str, int]]:
    """Each property's share dealt out over `workers` processes (the first ones take the remainders); a worker
    left without examples of a property does not run it."""
    plans: list[dict[str, int]] = [{} for _ in range(workers)]
    for name, share in shares.items():
        for w, plan in enumerate(plans):
            count = share // workers + (1 if w < share % workers else 0)
            if count:
                plan[name] = count
    return [plan for plan in plans if plan]


def _examples(tally: Tally) -> int:
    return sum(tally[k] for k in ("compiled by MuJoCo", "rejected by MuJoCo"))


def run_shares(plan: dict[str, int], database: Path = DATABASE, tally: Tally | None = None) -> Tally:
    """Run each property of `plan` for its number of examples, in this process; a failing property raises
    (after hypothesis shrank it and saved the counterexample)."""
    tally = Tally() if tally is None else tally
    for name, share in plan.items():
        before = _examples(tally)
        t0 = time.perf_counter()
        hypothesis_test(name, fuzz_settings(share, database), tally=tally)()
        log.info("%s: %d examples in %.1f s", name, _examples(tally) - before, time.perf_counter() - t0)
    return tally


def _worker(plan: dict[str, int], database: Path) -> tuple[Tally, str | None]:
    """`run_shares` in a worker process: its tally and, when a property failed, the error as text (hypothesis
    has printed the falsifying example; the shrunk document is saved under its content's hash, so workers that
    find the same one write the same file)."""
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    tally = Tally()
    try:
        run_shares(plan, database, tally)
    except Exception as error:  # noqa: BLE001 - reported by the parent, which fails the run
        return tally, "".join(traceback.format_exception(error))
    return tally, None


def _children_cpu() -> float:
    """CPU seconds of this process's finished child processes (the workers)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(examples: int, names: list[str], database: Path = DATABASE, workers: int = 1) -> float:
    """Run `examples` in total over the properties, in `workers` processes (each a share of every property, with
    its own random seed, one example database); returns examples per second (and prints the summary). A failing
    property fails the run: at once with one worker, after the other workers finish with more."""
    shares = split(examples, names)
    start = time.perf_counter()
    cpu = time.process_time() + _children_cpu()
    if workers <= 1:
        tally, errors = run_shares(shares, database), []
    else:
        plans = divide(shares, workers)
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: no PhysX or MuJoCo state copied
        with ProcessPoolExecutor(len(plans), mp_context=context) as pool:
            results = list(pool.map(_worker, plans, [database] * len(plans)))
        tally, errors = Tally(), [error for _, error in results if error]
        for part, _ in results:
            tally.update(part)
    elapsed = time.perf_counter() - start
    cpu = time.process_time() + _children_cpu() - cpu
    count = _examples(tally)
    rate = count / elapsed if elapsed else 0.0
    for key, value in sorted(tally.items()):
        print(f"  {key}: {value}")
    print(
        f"fuzz: {count} examples in {elapsed:.1f} s = {rate:.1f} examples/s, {workers} worker(s), "
        f"{cpu:.0f} CPU s ({', '.join(names)})"
    )
    if errors:
        raise AssertionError("a property failed in a worker:\n" + "\n".join(errors))
    return rate


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m conformance.fragments", description="Fuzz the loader with generated MJCF fragments."
    )
    parser.add_argument(
        "--examples", type=int, default=1000, help="examples in total, shared among the properties (default 1000)"
    )
    parser.add_argument(
        "--properties", default=",".join(PROPERTIES), help=f"comma-separated subset of {', '.join(PROPERTIES)}"
    )
    parser.add_argument("--database", type=Path, default=DATABASE, help="hypothesis example database folder")
    parser.add_argument(
        "--workers",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="processes sharing the examples (default: 2, or 1 on a single core)",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    names = [n.strip() for n in args.properties.split(",") if n.strip()]
    unknown = sorted(set(names) - set(PROPERTIES))
    if unknown:
        parser.error(f"unknown properties {unknown}; known: {sorted(PROPERTIES)}")
    run(args.examples, names, args.database, args.workers)
    return 0


__all__ = [
    "CI_EXAMPLES",
    "PROPERTIES",
    "STATIC_TIERS",
    "ci_settings",
    "divide",
    "fuzz_settings",
    "hypothesis_test",
    "main",
    "mutation_settings",
    "run",
    "run_shares",
    "split",
]
