"""Shrunk counterexamples as minimal MJCF files in `corpus/regressions/`, replayed by the test suite forever.

A failing property saves its document on hypothesis's final replay (the shrunk example) when the regression
folder exists (a source checkout). Known loader bugs are listed in `known_bugs.toml` beside the files, each
with the reason the replaying test is expected to fail.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

import tomllib

from ..corpus import corpus_root
from .document import Document, RawDocument, write

log = logging.getLogger(__name__)
REGRESSIONS = corpus_root() / "regressions"
KNOWN_BUGS = "known_bugs.toml"
# set to "0" to keep failing runs from writing into the corpus (e.g. while developing a mutation)
SAVE_ENV = "FRAGMENTS_SAVE_REGRESSIONS"


def regression_dir() -> Path:
    return Path(os.environ.get("FRAGMENTS_REGRESSION_DIR", REGRESSIONS))


def save_regression(document: Document | RawDocument, property_name: str, folder: Path | None = None) -> Path:
    """Write `document` as `<property>-<hash>.xml` (meshes as `<property>-<hash>.<mesh>.obj`). The hash covers
    the mesh files too: fuzz workers that save at once write either different names or the same bytes."""
    folder = Path(folder or regression_dir())
    xml, files = document.render()
    digest = hashlib.sha1(xml.encode())
    for name, text in sorted(files.items()):
        digest.update(f"\0{name}\0{text}".encode())
    stem = f"{property_name}-{digest.hexdigest()[:10]}"
    path = write(document, folder, stem)
    log.warning("fragments: counterexample of %s saved as %s", property_name, path)
    return path


def save_if_final(document: Document | RawDocument, property_name: str) -> Path | None:
    """Save on hypothesis's final replay of a failing example (the shrunk one); otherwise do nothing."""
    if os.environ.get(SAVE_ENV, "1") == "0" or not regression_dir().is_dir():
        return None
    try:
        from hypothesis.control import current_build_context

        final = getattr(current_build_context(), "is_final", False)
    except Exception:  # noqa: BLE001 - outside a hypothesis test: nothing to shrink, nothing to save
        return None
    return save_regression(document, property_name) if final else None


def regression_files(folder: Path | None = None) -> list[Path]:
    folder = Path(folder or regression_dir())
    return sorted(folder.glob("*.xml")) if folder.is_dir() else []


def _bugs(folder: Path | None) -> dict[str, dict]:
    path = Path(folder or regression_dir()) / KNOWN_BUGS
    return tomllib.loads(path.read_text()).get("bug", {}) if path.is_file() else {}


def known_bugs(folder: Path | None = None) -> dict[str, str]:
    """File name -> reason, for regressions that reproduce a known, still open loader bug."""
    return {name: str(entry["reason"]) for name, entry in _bugs(folder).items()}


def terms_bugs(folder: Path | None = None) -> set[str]:
    """The known bugs that live in the per-step terms' law alone (`law = "terms"`): their files replay clean where
    MuJoCo's own step gives the joint forces (the loader's default), and fail where the terms do."""
    return {name for name, entry in _bugs(folder).items() if entry.get("law") == "terms"}
