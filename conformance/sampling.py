"""Seeded random joint configurations for the kinematic tiers."""

from __future__ import annotations

import mujoco
import numpy as np

_UNLIMITED_HINGE = np.pi  # rad either side of qpos0
_UNLIMITED_SLIDE = 0.2  # m either side of qpos0
_FREE_POSITION = 0.5  # m either side of qpos0


def random_unit_quaternion(gen: np.random.Generator) -> np.ndarray:
    q = gen.standard_normal(4)
    return q / np.linalg.norm(q)


def random_configuration(model: mujoco.MjModel, gen: np.random.Generator) -> np.ndarray:
    """A qpos with every joint drawn uniformly within its range (or a bounded span if unlimited)."""
    qpos = model.qpos0.copy()
    for j in range(model.njnt):
        a = model.jnt_qposadr[j]
        kind = model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            qpos[a : a + 3] += gen.uniform(-_FREE_POSITION, _FREE_POSITION, 3)
            qpos[a + 3 : a + 7] = random_unit_quaternion(gen)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            qpos[a : a + 4] = random_unit_quaternion(gen)
        else:
            span = _UNLIMITED_HINGE if kind == mujoco.mjtJoint.mjJNT_HINGE else _UNLIMITED_SLIDE
            lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-np.inf, np.inf)
            if np.isinf(lo) and np.isinf(hi):  # unlimited, or a range open at both ends
                lo, hi = qpos[a] - span, qpos[a] + span
            elif np.isinf(lo) or np.isinf(hi):  # open at one end: the bounded span from the other
                lo, hi = (hi - 2 * span, hi) if np.isinf(lo) else (lo, lo + 2 * span)
            qpos[a] = gen.uniform(lo, hi)
    return qpos


def quaternion_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle between unit quaternions (..., 4), sign-insensitive; atan2 stays accurate near 0."""
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    q2 = q2 / np.linalg.norm(q2, axis=-1, keepdims=True)
    q2 = np.where(np.sum(q1 * q2, axis=-1, keepdims=True) < 0, -q2, q2)
    return 4 * np.arctan2(np.linalg.norm(q1 - q2, axis=-1), np.linalg.norm(q1 + q2, axis=-1))


def line_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions, sign ignored (lines); atan2 stays accurate near 0."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(np.dot(a, b))))


def direction_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions, sign included."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))
