"""Cameras and sites: where they are, in the frame of the body that carries them."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import sapien

from ..model import mj
from ..model.frames import mat_to_quat, pose, quat_mul, unit_quat

# SAPIEN cameras look along +X with +Z up; MuJoCo's look along -Z with +Y up.
# Columns: SAPIEN's x, y, z axes written in MuJoCo camera axes.
_SAPIEN_FROM_MUJOCO_CAMERA = mat_to_quat(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]]))


@dataclass
class CameraConfig:
    name: str
    body: str  # name of the body carrying the camera ("world" for fixed cameras)
    pose: sapien.Pose  # SAPIEN camera frame (x forward, z up) in the body frame
    fovy: float  # radians
    width: int
    height: int
    near: float = 0.01
    far: float = 100.0


@dataclass
class SiteConfig:
    name: str
    body: str
    pose: sapien.Pose  # in the body frame


def cameras(model: mujoco.MjModel) -> list[CameraConfig]:
    result = []
    for c in range(model.ncam):
        q = quat_mul(unit_quat(model.cam_quat[c]), _SAPIEN_FROM_MUJOCO_CAMERA)
        width, height = (int(x) for x in model.cam_resolution[c])
        result.append(
            CameraConfig(
                name=mj.name(model, "camera", c),
                body=mj.name(model, "body", int(model.cam_bodyid[c])),
                pose=pose(model.cam_pos[c], q),
                fovy=float(np.deg2rad(model.cam_fovy[c])),
                width=width,
                height=height,
                near=float(model.vis.map.znear * model.stat.extent),
                far=float(model.vis.map.zfar * model.stat.extent),
            )
        )
    return result


def sites(model: mujoco.MjModel) -> dict[str, SiteConfig]:
    result = {}
    rows = zip(model.site_bodyid.tolist(), model.site_pos.tolist(), model.site_quat.tolist())
    for s, (body, position, quat) in enumerate(rows):
        name = mj.name(model, "site", s)
        result[name] = SiteConfig(name, mj.name(model, "body", body), pose(position, quat))
    return result
