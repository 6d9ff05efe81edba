"""Typed errors and report entries of the loader."""

from __future__ import annotations

import re
from dataclasses import dataclass, field


class MJCFError(Exception):
    """MuJoCo rejected the document (or a part the loader needs is missing).

    `file` and `line` name where, when MuJoCo said so; `mujoco_message` is MuJoCo's own text.
    """

    def __init__(self, file: str, mujoco_message: str, hint: str = "", rejected_by: str = "MuJoCo rejected the model"):
        self.file = str(file)
        self.mujoco_message = mujoco_message.strip()
        match = re.search(r"line (\d+)", self.mujoco_message, re.IGNORECASE) or re.search(
            r"Line number=(\d+)", self.mujoco_message
        )
        self.line: int | None = int(match.group(1)) if match else None
        element = re.search(r"Element (?:name )?'([^']*)'", self.mujoco_message)
        self.element: str | None = element.group(1) if element else None
        where = f"{self.file}" + (f", line {self.line}" if self.line is not None else "")
        text = f"{where}: {rejected_by}: {self.mujoco_message}"
        if hint:
            text += f"\n  fix: {hint}"
        super().__init__(text)


class MissingAssetError(MJCFError):
    """A mesh, height field or texture file named by the model cannot be read."""


class ControlError(ValueError):
    """A command `set_ctrl` / `step` cannot apply: the wrong size, or a value that is not finite or beyond what
    MuJoCo accepts (mjMAXVAL). Nothing of the
    scene or of the activations has changed when it is raised."""


class DivergenceError(RuntimeError):
    """SAPIEN's state is no longer finite: `set_ctrl` (and `step`) refuse it, naming the first DoF that is not and the
    physics steps `set_ctrl` has run, rather than stepping NaN on
    (tests/test_loader_errors.py::test_a_state_that_is_no_longer_finite_is_refused_naming_the_dof_and_the_step)."""


def command_vector(path: str, name: str, value, size: int, what: str):
    """`value` as a float64 vector of `size` finite numbers (None stays None), else ControlError naming the model
    file, the argument and the fix."""
    import mujoco
    import numpy as np

    if value is None:
        return None
    vector = np.asarray(value, dtype=np.float64)
    if vector.shape != (size,):
        raise ControlError(
            f"{path}: {name} has shape {vector.shape}; the model has {size} {what}: pass a vector "
            f"of {size} numbers (or None for zeros)"
        )
    if np.count_nonzero(np.abs(vector) <= mujoco.mjMAXVAL) == size:  # finite and within MuJoCo's bound
        return vector
    bad = np.flatnonzero(~np.isfinite(vector))
    if bad.size:
        raise ControlError(f"{path}: {name}[{int(bad[0])}] is {vector[bad[0]]}: every entry must be finite")
    huge = np.flatnonzero(np.abs(vector) > mujoco.mjMAXVAL)  # MuJoCo zeroes such a command and warns
    if huge.size:
        raise ControlError(
            f"{path}: {name}[{int(huge[0])}] is {vector[huge[0]]:g}: MuJoCo refuses commands beyond "
            f"{mujoco.mjMAXVAL:g} (it zeroes them as unstable); pass values within that"
        )
    return vector


@dataclass(frozen=True)
class Note:
    """What the loader says of one element: `kind` is the MJCF concept, `name` the element, `reason` why."""

    kind: str
    name: str
    reason: str

    def __str__(self) -> str:
        return f"{self.kind} '{self.name}': {self.reason}"


@dataclass(frozen=True)
class Unsupported(Note):
    """A model feature the loader dropped: SAPIEN does not have it (`LoadResult.unsupported`)."""


@dataclass(frozen=True)
class Approximation(Note):
    """A model feature the loader maps by a law that is not MuJoCo's exactly; the reason says which
    (`LoadResult.approximations`)."""


class UnsupportedFeatureWarning(UserWarning):
    """A model feature was dropped (or, where asked for, approximated); the load result lists each one."""


class SceneMismatchWarning(UserWarning):
    """A scene given with `MJCFLoader.set_scene` simulates differently from the model (timestep, gravity, solver);
    the message names each difference and what to set."""


@dataclass
class Notes:
    """What a load could not map exactly: `unsupported` is dropped, `approximations` is mapped inexactly."""

    unsupported: list[Unsupported] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)

    def drop(self, kind: str, name: str, reason: str) -> None:
        self.unsupported.append(Unsupported(kind, name, reason))

    def approximate(self, kind: str, name: str, reason: str) -> None:
        self.approximations.append(Approximation(kind, name, reason))

    def extend(self, other: Notes) -> None:
        """Take `other`'s notes too (after this one's)."""
        self.unsupported += other.unsupported
        self.approximations += other.approximations


def warn_notes(
    path,
    unsupported: list[Unsupported],
    approximations: list[Approximation],
    each: bool = False,
    stacklevel: int = 3,
) -> None:
    """UnsupportedFeatureWarning for a load's notes: one per category and kind, with the count and the first note
    (the lists on the result hold every one), or one per note with `each`; pass no `approximations` to warn of
    what was dropped alone
    (tests/test_loader_structure.py::test_unsupported_features_are_listed_and_warned_once_per_kind)."""
    import warnings
    from pathlib import Path

    name = Path(str(path)).name
    for category, notes in (("unsupported", unsupported), ("approximated", approximations)):
        if each:
            for note in notes:
                warnings.warn(f"{name}: {category} {note}", UnsupportedFeatureWarning, stacklevel=stacklevel)
            continue
        kinds: dict[str, list[Note]] = {}
        for note in notes:
            kinds.setdefault(note.kind, []).append(note)
        listed = "result.unsupported" if category == "unsupported" else "result.approximations"
        for kind, same in kinds.items():
            more = f"; {len(same) - 1} more in {listed}" if len(same) > 1 else ""
            warnings.warn(
                f"{name}: {category} {kind} x{len(same)}: '{same[0].name}': {same[0].reason}{more}",
                UnsupportedFeatureWarning,
                stacklevel=stacklevel,
            )
