"""The properties as hypothesis tests, their profiles, and the `fuzz` command.

Profiles: "ci" is derandomized and bounded (inside the normal test suite); "fuzz" draws many examples and keeps
hypothesis's example database between runs (`.hypothesis/fragments`), so failures found once are replayed
first next time.
"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Callable
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
    return settings(max_examples=examples, derandomize=True, database=None, deadline=None,
                    suppress_health_check=_HEALTH, print_blob=False)


def fuzz_settings(examples: int, database: Path = DATABASE) -> settings:
    return settings(max_examples=examples, database=DirectoryBasedExampleDatabase(str(database)), deadline=None,
                    suppress_health_check=_HEALTH, print_blob=True)


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
    assert_conforms(document, tiers=("structure", "kinematics"), dynamics=False, actuators=False,
                    property_name="kinematics", tally=tally)


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


def hypothesis_test(name: str, profile: settings, with_examples: bool = True,
                    tally: Tally | None = None) -> Callable[[], None]:
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


def run(examples: int, names: list[str], database: Path = DATABASE) -> float:
    """Run `examples` in total over the properties; returns examples per second (and prints the summary)."""
    tally = Tally()
    count = 0
    start = time.perf_counter()
    for name, share in split(examples, names).items():
        before = sum(tally[k] for k in ("compiled by MuJoCo", "rejected by MuJoCo"))
        t0 = time.perf_counter()
        hypothesis_test(name, fuzz_settings(share, database), tally=tally)()
        done = sum(tally[k] for k in ("compiled by MuJoCo", "rejected by MuJoCo")) - before
        count += done
        log.info("%s: %d examples in %.1f s", name, done, time.perf_counter() - t0)
    elapsed = time.perf_counter() - start
    rate = count / elapsed if elapsed else 0.0
    for key, value in sorted(tally.items()):
        print(f"  {key}: {value}")
    print(f"fuzz: {count} examples in {elapsed:.1f} s = {rate:.1f} examples/s ({', '.join(names)})")
    return rate


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m conformance.fragments",
                                     description="Fuzz the loader with generated MJCF fragments.")
    parser.add_argument("--examples", type=int, default=1000, help="examples in total, shared among the properties (default 1000)")
    parser.add_argument("--properties", default=",".join(PROPERTIES),
                        help=f"comma-separated subset of {', '.join(PROPERTIES)}")
    parser.add_argument("--database", type=Path, default=DATABASE, help="hypothesis example database folder")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    names = [n.strip() for n in args.properties.split(",") if n.strip()]
    unknown = sorted(set(names) - set(PROPERTIES))
    if unknown:
        parser.error(f"unknown properties {unknown}; known: {sorted(PROPERTIES)}")
    run(args.examples, names, args.database)
    return 0


__all__ = ["CI_EXAMPLES", "PROPERTIES", "STATIC_TIERS", "ci_settings", "fuzz_settings", "hypothesis_test", "main",
           "mutation_settings", "run", "split"]
