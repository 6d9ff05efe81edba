"""MuJoCo is the front end: parse with MjSpec, compile with MuJoCo, and turn its rejections into typed errors."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import mujoco

from ..errors import MissingAssetError, MJCFError
from ..model import mj

_MISSING_FILE_SIGNS = ("error opening file", "resource not found", "could not open", "file not found")


@dataclass
class CompiledModel:
    """The authored structure (`spec`) beside the compiled numbers (`model`) of one MJCF document, and MuJoCo's
    forward pass at qpos0 (`at_qpos0`, which the build reads through `mj.sharing_qpos0`)."""

    path: Path
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    at_qpos0: mujoco.MjData


def _raise_for(path: Path, error: Exception) -> None:
    message = str(error)
    if any(sign in message.lower() for sign in _MISSING_FILE_SIGNS):
        raise MissingAssetError(
            path, message, hint="check the asset's file name against the compiler's meshdir/texturedir"
        ) from None
    raise MJCFError(
        path, message, hint="correct the element MuJoCo names; the loader accepts what MuJoCo compiles"
    ) from None


def compile_mjcf(
    mjcf_file: str | os.PathLike | mujoco.MjSpec, package_dir: str | os.PathLike | None = None
) -> CompiledModel:
    """Parse and compile `mjcf_file` with MuJoCo; an `MjSpec` (built or edited in Python) is compiled as it is.

    `package_dir`, when given, is where relative mesh and texture directories are looked up instead of the
    document's own folder.
    """
    if isinstance(mjcf_file, mujoco.MjSpec):
        spec = mjcf_file
        path = Path(spec.modelfiledir or ".") / f"{spec.modelname or 'spec'}.xml"
    else:
        path = Path(mjcf_file)
        if not path.is_file():
            raise MJCFError(path, f"no such file: {path}", hint="pass the path of an MJCF .xml file or an MjSpec")
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as error:
            _raise_for(path, error)
    if package_dir is not None:
        for attribute in ("meshdir", "texturedir"):
            current = getattr(spec, attribute) or ""
            if not os.path.isabs(current):
                setattr(spec, attribute, os.path.join(os.fspath(package_dir), current))
    try:
        model = spec.compile()
    except ValueError as error:
        _raise_for(path, error)
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
    return CompiledModel(path=path, spec=spec, model=model, at_qpos0=at_qpos0)
