"""Third-party warnings stay off the terminal: silenced where they say nothing about a model, counted where they do.

- SAPIEN warns at import, in every worker process, that it found no system libvulkan and uses its own: nothing about
  any model, so `silence_imports` drops it (the package calls it before anything imports SAPIEN).
- MuJoCo's warnings (a deprecated attribute at compile, solver warnings while stepping) go through `Tally`'s handler
  instead of MuJoCo's, which prints them and writes `MUJOCO_LOG.TXT` into the working directory: they are counted and
  appended to the run folder's `MUJOCO_LOG.TXT`.
- Python warnings raised while a model is evaluated (MuJoCo's compile warnings, numpy's All-NaN slice) are counted.

The counts go into each model's result (`warnings`) and one line of the run's terminal output.
Tests: tests/test_conformance_runner.py::test_third_party_warnings_are_counted_not_printed.
"""

from __future__ import annotations

import re
import warnings
from collections import Counter
from datetime import datetime
from pathlib import Path

MUJOCO_LOG = "MUJOCO_LOG.TXT"
_NUMBER = re.compile(r"\d+(?:\.\d+)?")


def silence_imports() -> None:
    """Drop the warnings third-party packages raise on import that say nothing about a model."""
    warnings.filterwarnings("ignore", message="Failed to find system libvulkan", category=UserWarning)


def kind(text: str) -> str:
    """A warning's kind: its first line with numbers as N (MuJoCo's solver warnings name a DoF and a time)."""
    first = str(text).strip().splitlines()[0] if str(text).strip() else ""
    return _NUMBER.sub("N", first)[:160]


class Tally:
    """Within the block: MuJoCo's warnings counted and logged into `run_dir/MUJOCO_LOG.TXT`, Python's counted;
    `counts` maps each kind to how often it came."""

    def __init__(self, run_dir: str | Path):
        self.log = Path(run_dir) / MUJOCO_LOG
        self.counts: Counter[str] = Counter()

    def _mujoco(self, message: str) -> None:
        self.counts[f"MuJoCo: {kind(message)}"] += 1
        with open(self.log, "a") as f:  # MuJoCo's own format
            f.write(f"WARNING {datetime.now().strftime('%a %b %d %H:%M:%S %Y')}: {message}\n\n")

    def __enter__(self):
        import mujoco

        self._catcher = warnings.catch_warnings(record=True)
        self._caught = self._catcher.__enter__()
        warnings.simplefilter("always")
        silence_imports()
        self._previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(self._mujoco)
        return self

    def __exit__(self, *exc) -> None:
        import mujoco

        mujoco.set_mju_user_warning(self._previous)
        self._catcher.__exit__(*exc)
        for caught in self._caught:
            self.counts[f"{caught.category.__name__}: {kind(caught.message)}"] += 1
