"""Textures as ManiSkill's loader exposes them, filled from the compiled model (built-in ones included)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np

_TYPES = {
    int(mujoco.mjtTexture.mjTEXTURE_2D): "2d",
    int(mujoco.mjtTexture.mjTEXTURE_CUBE): "cube",
    int(mujoco.mjtTexture.mjTEXTURE_SKYBOX): "skybox",
}

from ..model import mj


@dataclass
class MJCFTexture:
    name: str
    type: Literal["skybox", "cube", "2d"]
    rgb1: list
    rgb2: list
    file: str
    # the pixels MuJoCo compiled (procedural textures are generated at compile time), height x width x channels:
    # a read-only view of the model's own (a skybox is megabytes, copied on every load otherwise)
    data: np.ndarray = field(default=None, repr=False)


def textures(spec: mujoco.MjSpec, model: mujoco.MjModel) -> list[MJCFTexture]:
    result = []
    for t, authored in enumerate(spec.textures):
        t = authored.id if authored.id >= 0 else t
        height, width, channels = (int(model.tex_height[t]), int(model.tex_width[t]), int(model.tex_nchannel[t]))
        start = int(model.tex_adr[t])
        pixels = model.tex_data[start : start + height * width * channels].reshape(height, width, channels)
        pixels.flags.writeable = False
        result.append(
            MJCFTexture(
                name=mj.name(model, "texture", t),
                type=_TYPES.get(int(model.tex_type[t]), "2d"),
                rgb1=[float(x) for x in authored.rgb1],
                rgb2=[float(x) for x in authored.rgb2],
                file=authored.file,
                data=pixels,
            )
        )
    return result
