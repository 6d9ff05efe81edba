"""Versions of everything a verdict depends on, recorded in every report."""

from __future__ import annotations

import importlib.metadata
import platform

_DISTRIBUTIONS = ("mujoco", "sapien", "rerun-sdk", "dm-control", "numpy")


def versions(extra: tuple[str, ...] = ()) -> dict[str, str]:
    """The distributions' versions (and `extra`'s: what another loader than this project's brings)."""
    out = {}
    for dist in _DISTRIBUTIONS + tuple(extra):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = "not installed"
    out["python"] = platform.python_version()
    return out


def project_version() -> str:
    """`mjcf-sapien <version>` and the simulators' versions, for `--version`."""
    try:
        own = importlib.metadata.version("mjcf-sapien")
    except importlib.metadata.PackageNotFoundError:
        own = "(not installed)"
    found = versions()
    return f"mjcf-sapien {own} (mujoco {found['mujoco']}, sapien {found['sapien']}, python {found['python']})"
