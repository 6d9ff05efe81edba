"""Poses as the recording needs them: (x, y, z, qw, qx, qy, qz) rows composed in numpy, and the motion the 3D view
plays (one rollout's MuJoCo body poses and SAPIEN link poses, or the start state when no rollout ran)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .. import sapien_side
from ..report import Trace


def xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(q_wxyz, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of wxyz quaternions, broadcast over leading axes."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v rotated by the wxyz quaternion q (broadcast)."""
    q = np.asarray(q, dtype=float)
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def compose(parent: np.ndarray, local: np.ndarray) -> np.ndarray:
    """World pose of a frame given in `parent`'s frame: both (..., 7) rows."""
    parent, local = np.asarray(parent, dtype=float), np.asarray(local, dtype=float)
    p = parent[..., :3] + rotate(parent[..., 3:], local[..., :3])
    q = quat_mul(parent[..., 3:], np.broadcast_to(local[..., 3:], parent[..., 3:].shape))
    return np.concatenate([p, q], axis=-1)


@dataclass
class Motion:
    """What the 3D view plays: `time` (T,) or None for a still scene, MuJoCo body poses (T, nbody, 7), SAPIEN link
    poses (T, L, 7), whether contacts were on, and the rollout's name."""

    name: str
    time: np.ndarray | None
    mujoco_body_pose: np.ndarray
    sapien_body_pose: np.ndarray
    sapien_link_pose: np.ndarray
    contact: bool

    @classmethod
    def of(cls, trace: Trace) -> Motion:
        return cls(
            trace.name,
            trace.time,
            trace.mujoco_body_pose,
            trace.sapien_body_pose,
            trace.sapien_link_pose,
            trace.contact,
        )

    @classmethod
    def still(cls, model: mujoco.MjModel, result) -> Motion:
        """The model at qpos0 as authored (contacts as the model has them), SAPIEN in its current state."""
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        bodies = np.concatenate([data.xpos, data.xquat], axis=1)[None]
        links = sapien_side.link_poses(result)[None]
        mapped = sapien_side.bodies_from_links(links, sapien_side.body_link_rows(result, model.nbody))
        return cls("start state", None, bodies, mapped, links, True)


def geom_local(model: mujoco.MjModel, g: int) -> np.ndarray:
    return np.concatenate([model.geom_pos[g], model.geom_quat[g]])


def geom_world(model: mujoco.MjModel, motion: Motion, g: int) -> np.ndarray:
    """(T, 7) world pose of geom g along the motion."""
    return compose(motion.mujoco_body_pose[:, int(model.geom_bodyid[g])], geom_local(model, g))
