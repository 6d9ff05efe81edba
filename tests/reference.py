"""MuJoCo as the oracle: poses, random configurations and the geom pairs MuJoCo lets touch."""

from __future__ import annotations

import mujoco
import numpy as np

from loader.frames import quat_conj, quat_mul


def random_qpos(model: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """A configuration within joint limits (unlimited hinges in [-pi, pi], slides in [-1, 1])."""
    q = model.qpos0.copy()
    for j in range(model.njnt):
        adr, jtype = model.jnt_qposadr[j], model.jnt_type[j]
        if jtype == mujoco.mjtJoint.mjJNT_FREE:
            q[adr : adr + 3] = rng.uniform(-1, 1, 3)
            quat = rng.normal(size=4)
            q[adr + 3 : adr + 7] = quat / np.linalg.norm(quat)
        elif jtype == mujoco.mjtJoint.mjJNT_BALL:
            quat = rng.normal(size=4)
            q[adr : adr + 4] = quat / np.linalg.norm(quat)
        else:
            default = (-np.pi, np.pi) if jtype == mujoco.mjtJoint.mjJNT_HINGE else (-1.0, 1.0)
            low, high = model.jnt_range[j] if model.jnt_limited[j] else default
            q[adr] = rng.uniform(low, high)
    return q


def body_poses(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data.xpos.copy(), data.xquat.copy()


def rotation_angle(q_a, q_b) -> float:
    """Angle of the rotation between two unit quaternions (wxyz), accurate near zero."""
    d = quat_mul(quat_conj(np.asarray(q_a, np.float64)), np.asarray(q_b, np.float64))
    return float(2 * np.arctan2(np.linalg.norm(d[1:]), abs(d[0])))


def touching_geom_pairs(spec: mujoco.MjSpec) -> set[tuple[int, int]]:
    """Geom pairs MuJoCo's collision pipeline keeps (its bit rule and body filters), found by turning every
    geom into a 100 m sphere at its body's origin so that every pair overlaps, then asking mj_collision."""
    spec = spec.copy()
    spec.memory = 1 << 28
    for geom in spec.geoms:
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [100.0, 0.0, 0.0]
        geom.meshname = ""
        geom.hfieldname = ""
        geom.fromto = [np.nan] * 6
        geom.pos = [0.0, 0.0, 0.0]
    probe = spec.compile()
    data = mujoco.MjData(probe)
    mujoco.mj_kinematics(probe, data)
    mujoco.mj_collision(probe, data)
    return {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in data.contact[: data.ncon]}
