"""Tier 2: link poses against MuJoCo body poses at qpos0 and at seeded random configurations."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import sapien_side
from ..commands import rng
from ..data_pool import borrowed
from ..report import TierReport, judged, metric, skipped
from ..sampling import quaternion_angle, random_configuration
from ..tolerances import Tolerances


def configurations(model: mujoco.MjModel, seed: int, count: int) -> list[np.ndarray]:
    gen = rng(seed, "kinematics")
    return [model.qpos0.copy()] + [random_configuration(model, gen) for _ in range(count)]


def kinematics(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    """World pose of the link carrying each body vs MuJoCo's `xpos`/`xquat` (bodies without a link skip)."""
    bodies = [b for b in range(1, model.nbody) if sapien_side.body_link(result, b) is not None]
    if not bodies:
        return skipped("kinematics", "no MuJoCo body is carried by an articulation link")
    with borrowed(model) as data:
        pos_err, rot_err = [], []
        configs = configurations(model, seed, int(tolerances.setting("kinematics", "random_configurations")))
        for qpos in configs:
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            sapien_side.set_state(result, qpos, np.zeros(model.nv))
            poses = sapien_side.body_poses(result, model.nbody)[bodies]
            pos_err.append(np.linalg.norm(poses[:, :3] - data.xpos[bodies], axis=1))
            rot_err.append(quaternion_angle(poses[:, 3:], data.xquat[bodies]))
        sapien_side.set_state(result, model.qpos0, np.zeros(model.nv))
        pos_err, rot_err = np.array(pos_err), np.array(rot_err)
        notes = []
        worst = np.unravel_index(np.argmax(pos_err), pos_err.shape)
        if pos_err.size:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, bodies[worst[1]]) or f"body{bodies[worst[1]]}"
            notes.append(f"largest position error at body {name!r}, configuration {worst[0]}")
        return judged(
            "kinematics",
            [
                metric("position", pos_err, tolerances["kinematics.position"], "m"),
                metric("orientation", rot_err, tolerances["kinematics.orientation"], "rad"),
            ],
            notes,
            settings={"configurations": len(configs), "bodies": len(bodies)},
            series={"position_error_per_configuration": pos_err.max(axis=1)},
        )
