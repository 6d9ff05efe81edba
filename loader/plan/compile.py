"""MuJoCo is the front end: parse with MjSpec, compile with MuJoCo, and turn its rejections into typed errors."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree.ElementTree import ParseError

import mujoco

from ..errors import MissingAssetError, MJCFError, Notes
from ..model import mj
from .dialect import FIXED_JOINT, drop_sensors_on, missing_sensor_target, without_fixed_joints

_MISSING_FILE_SIGNS = ("error opening file", "resource not found", "could not open", "file not found")


@dataclass
class CompiledModel:
    """The authored structure (`spec`) beside the compiled numbers (`model`) of one MJCF document, and MuJoCo's
    forward pass at qpos0 (`at_qpos0`, which the build reads through `mj.sharing_qpos0`); `notes`: what the
    compile removed from a file in ManiSkill's dialect (`dialect.py`)."""

    path: Path
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    at_qpos0: mujoco.MjData
    notes: Notes = field(default_factory=Notes)


def _raise_for(path: Path, error: Exception) -> None:
    message = str(error)
    if any(sign in message.lower() for sign in _MISSING_FILE_SIGNS):
        raise MissingAssetError(
            path, message, hint="check the asset's file name against the compiler's meshdir/texturedir"
        ) from None
    raise MJCFError(
        path, message, hint="correct the element MuJoCo names; the loader accepts what MuJoCo compiles"
    ) from None


def _readable(mjcf_file: str | os.PathLike) -> Path:
    """The path of an MJCF file to read, or MJCFError saying why there is none: an XML document passed as a string,
    a folder, a path with no file (relative paths start at the working directory)."""
    if isinstance(mjcf_file, str) and mjcf_file.lstrip().startswith("<"):
        raise MJCFError(
            "<string>",
            "an MJCF document was passed as text",
            rejected_by="the loader takes a file",
            hint="pass a path or an MjSpec; for a string use mujoco.MjSpec.from_string(text)",
        )
    path = Path(mjcf_file)
    if path.is_dir():
        raise MJCFError(
            path, "it is a folder", rejected_by="the loader takes a file", hint="pass the model's .xml file"
        )
    if not path.is_file():
        where = "" if path.is_absolute() else f" (relative to {Path.cwd()})"
        raise MJCFError(
            path,
            f"nothing at this path{where}",
            rejected_by="no such file",
            hint="pass the path of an MJCF .xml file or an MjSpec (`python -m conformance where NAME` prints where a "
            "corpus model is)",
        )
    return path


def compile_mjcf(
    mjcf_file: str | os.PathLike | mujoco.MjSpec, package_dir: str | os.PathLike | None = None, dialect: bool = False
) -> CompiledModel:
    """Parse and compile `mjcf_file` with MuJoCo; an `MjSpec` (built or edited in Python) is compiled as it is.

    `package_dir`, when given, is where relative mesh and texture directories are looked up instead of the
    document's own folder. `dialect`: a file MuJoCo rejects only for ManiSkill's spellings is read again without
    them (`dialect.py`).
    """
    notes = Notes()
    if isinstance(mjcf_file, mujoco.MjSpec):
        spec = mjcf_file
        path = Path(spec.modelfiledir or ".") / f"{spec.modelname or 'spec'}.xml"
    else:
        path = _readable(mjcf_file)
        spec = _parsed(path, notes if dialect else None)
    if package_dir is not None:
        for attribute in ("meshdir", "texturedir"):
            current = getattr(spec, attribute) or ""
            if not os.path.isabs(current):
                setattr(spec, attribute, os.path.join(os.fspath(package_dir), current))
    model = _compiled(spec, path, notes if dialect and not isinstance(mjcf_file, mujoco.MjSpec) else None)
    try:  # MuJoCo compiles some models it cannot run: an arena too small for thousands of bodies, say
        at_qpos0 = mj.forward_at(model)
    except mujoco.FatalError as error:
        raise MJCFError(
            path,
            str(error).replace(", line ", ":"),
            rejected_by="MuJoCo cannot run the compiled model",
            hint="MuJoCo's forward pass at qpos0 fails; where it says out of memory, raise "
            '<size memory=...> (e.g. memory="512M")',
        ) from None
    return CompiledModel(path=path, spec=spec, model=model, at_qpos0=at_qpos0, notes=notes)


def _parsed(path: Path, notes: Notes | None) -> mujoco.MjSpec:
    """MuJoCo's parse of the file; with `notes` (the dialect), a file it rejects only for ManiSkill's fixed joints is
    parsed without them."""
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as error:
        if notes is None or FIXED_JOINT not in str(error):
            _raise_for(path, error)
    try:
        return without_fixed_joints(path, notes)
    except (ValueError, ParseError) as error:
        _raise_for(path, error)


def _compiled(spec: mujoco.MjSpec, path: Path, notes: Notes | None) -> mujoco.MjModel:
    """MuJoCo's compile of the spec; with `notes` (a file read in the dialect), a sensor on an object the file never
    defines is removed and the compile tried again (ManiSkill's loader reads no sensor)."""
    while True:
        try:
            return spec.compile()
        except ValueError as error:
            target = missing_sensor_target(str(error))
            if notes is None or target is None or not drop_sensors_on(spec, target, notes):
                _raise_for(path, error)
