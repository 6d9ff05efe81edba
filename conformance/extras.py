"""Which of the project's extras the command line needs, checked before anything imports them: a core install
(`pip install .`) has the `conformance` package but not the harness's packages, and says which extra to install
(tests/test_packaging.py::test_the_core_install_names_the_harness_extra)."""

from __future__ import annotations

import importlib.util

HARNESS = {"rerun": "rerun-sdk", "dm_control": "dm-control", "tqdm": "tqdm"}  # module -> its distribution


def missing_harness() -> str | None:
    """The message naming the `harness` extra and what of it is missing, or None when it is installed."""
    missing = [package for module, package in HARNESS.items() if importlib.util.find_spec(module) is None]
    if not missing:
        return None
    return (
        f"python -m conformance needs the harness extra ({', '.join(missing)} missing): "
        "pip install 'mjcf-sapien[harness]' (from a clone: pip install '.[harness]', or run it through "
        "`pipx run nox -s conformance`)"
    )
