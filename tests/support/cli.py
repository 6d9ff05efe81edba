"""`python -m conformance run ...` as a subprocess, the way a user runs it, for the tests of the command line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SELFTEST = ROOT / "corpus" / "selftest.toml"


def run_cli(*args: str, timeout: float = 300, cwd: Path = ROOT, **options) -> subprocess.CompletedProcess:
    """The run's completed process (text output captured; `options` go to `subprocess.run`, e.g. `env`)."""
    return subprocess.run(
        [sys.executable, "-m", "conformance", "run", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        **options,
    )


def run_selftest(model: str, out: Path, *args: str, **options) -> subprocess.CompletedProcess:
    """`run_cli` over the self-test manifest's `model`, into `out`, quiet and unrecorded, with more `args`."""
    return run_cli(
        "--manifest", str(SELFTEST), "--model", model, "--out", str(out), "--quiet", "--no-record", *args, **options
    )
