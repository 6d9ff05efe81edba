"""Rigid-frame helpers. Quaternions are (w, x, y, z) as in MuJoCo and SAPIEN."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import sapien

_S = np.sqrt(0.5)
# SAPIEN capsules, cylinders and planes run along (or face) local +X; MuJoCo's along +Z.
# This rotation (-90 degrees about Y) carries +X onto +Z.
X_TO_Z = np.array([_S, 0.0, -_S, 0.0])


def _floats(v) -> list[float]:
    return v.tolist() if isinstance(v, np.ndarray) else [float(c) for c in v]


def _unit(q) -> list[float]:
    w, x, y, z = _floats(q)
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    return [w / norm, x / norm, y / norm, z / norm] if norm >= mujoco.mjMINVAL else [1.0, 0.0, 0.0, 0.0]


def unit_quat(q) -> np.ndarray:
    """`q` normalized in float64 before SAPIEN's float32 sees it (one shorter than mjMINVAL, which
    `plan/numbers.py` rejects before any pose is built, is the identity rather than NaN). On Python floats: a load
    builds hundreds of poses, and numpy's call costs more than the arithmetic (the same numbers as numpy's norm)."""
    return np.array(_unit(q))


def pose(p, q=(1.0, 0.0, 0.0, 0.0)) -> sapien.Pose:
    return sapien.Pose(_floats(p), _unit(q))


def quat_mul(a, b) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_conj(q) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


Vec3 = tuple[float, float, float]


def rotation_rows(q) -> tuple[Vec3, Vec3, Vec3]:
    """The rotation of the quaternion `q` (normalized first) as three rows of floats. Per-step code turns a handful
    of 3-vectors, and a numpy call costs more than the arithmetic (`turn`, `turn_back`, `cross_floats`)."""
    w, x, y, z = q.tolist() if isinstance(q, np.ndarray) else (float(c) for c in q)
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def quat_to_mat(q) -> np.ndarray:
    return np.array(rotation_rows(q))


def turn(rows: tuple[Vec3, Vec3, Vec3], v) -> Vec3:
    """R v, R given by its rows (`rotation_rows`)."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = rows
    x, y, z = v
    return (a0 * x + a1 * y + a2 * z, b0 * x + b1 * y + b2 * z, c0 * x + c1 * y + c2 * z)


def turn_back(rows: tuple[Vec3, Vec3, Vec3], v) -> Vec3:
    """R^T v, R given by its rows (`rotation_rows`)."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = rows
    x, y, z = v
    return (a0 * x + b0 * y + c0 * z, a1 * x + b1 * y + c1 * z, a2 * x + b2 * y + c2 * z)


def cross_floats(a, b) -> Vec3:
    """a x b of two 3-vectors, as floats when they hold floats."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


LEVI_CIVITA = np.array(
    [[[0, 0, 0], [0, 0, 1], [0, -1, 0]], [[0, 0, -1], [0, 0, 0], [1, 0, 0]], [[0, 1, 0], [-1, 0, 0], [0, 0, 0]]],
    dtype=np.float64,
)


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b row by row for (n, 3) arrays, in one call (numpy's `cross` costs several times as much)."""
    return np.einsum("ijk,nj,nk->ni", LEVI_CIVITA, a, b)


def cross(a, b) -> np.ndarray:
    """a x b for 3-vectors as an array (numpy's own `cross` costs several times the arithmetic, on every step)."""
    return np.array(cross_floats(a, b))


def solve_symmetric(m: Vec3 | tuple, b) -> Vec3:
    """x with S x = b, S symmetric positive definite given as (xx, yy, zz, xy, xz, yz) (MuJoCo's order for
    inertia), by its cofactors."""
    xx, yy, zz, xy, xz, yz = m
    c_xx, c_yy, c_zz = yy * zz - yz * yz, xx * zz - xz * xz, xx * yy - xy * xy
    c_xy, c_xz, c_yz = xz * yz - xy * zz, xy * yz - xz * yy, xy * xz - xx * yz
    det = xx * c_xx + xy * c_xy + xz * c_xz
    x, y, z = b
    return (
        (c_xx * x + c_xy * y + c_xz * z) / det,
        (c_xy * x + c_yy * y + c_yz * z) / det,
        (c_xz * x + c_yz * y + c_zz * z) / det,
    )


def mat_to_quat(r) -> np.ndarray:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(r, dtype=np.float64).reshape(9))
    return q


def quat_from_axis_angle(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


# Rotations carrying +X onto a coordinate axis whose quaternions float32 holds exactly (120 degree turns about a cube
# diagonal; -X is the half turn about Z below): the shortest rotation onto +Y or +Z has components sqrt(1/2), which
# float32 rounds, tilting the joint's axis. Under gravity that tilt turns a light body on a vertical hinge, where
# MuJoCo's stays still (tests/test_loader_joints.py::test_a_light_body_on_a_vertical_hinge_stays_at_rest_under_gravity).
EXACT_X_TO = {
    (0, 1, 0): (0.5, 0.5, 0.5, 0.5),
    (0, -1, 0): (0.5, 0.5, -0.5, -0.5),
    (0, 0, 1): (0.5, 0.5, -0.5, 0.5),
    (0, 0, -1): (0.5, 0.5, 0.5, -0.5),
}


def quat_x_to(axis) -> np.ndarray:
    """A rotation that carries +X onto `axis` (a joint frame for SAPIEN, whose joints act along +X): exact in float32
    for a coordinate axis, otherwise the shortest one."""
    x, y, z = _floats(axis)
    norm = math.sqrt(x * x + y * y + z * z)
    x, y, z = x / norm, y / norm, z / norm
    for unit, q in EXACT_X_TO.items():
        if max(abs(x - unit[0]), abs(y - unit[1]), abs(z - unit[2])) < 1e-12:
            return np.array(q)
    if x < -1.0 + 1e-12:
        return np.array([0.0, 0.0, 0.0, 1.0])  # half turn about Z
    return np.array(_unit((1.0 + x, 0.0, -z, y)))


def euler_xyz_from_quat(q) -> np.ndarray:
    """Angles (a, b, c) with R(q) = Rx(a) Ry(b) Rz(c): the three revolutes that stand in for a ball joint."""
    r = quat_to_mat(q)
    b = np.arcsin(np.clip(r[0, 2], -1.0, 1.0))
    a = np.arctan2(-r[1, 2], r[2, 2])
    c = np.arctan2(-r[0, 1], r[0, 0])
    return np.array([a, b, c])


def quat_from_euler_xyz(angles) -> np.ndarray:
    a, b, c = angles
    q = quat_mul(quat_from_axis_angle((1, 0, 0), a), quat_from_axis_angle((0, 1, 0), b))
    return quat_mul(q, quat_from_axis_angle((0, 0, 1), c))


def euler_xyz_rate_matrix(angles) -> np.ndarray:
    """E with omega_child_frame = E @ (a', b', c') for R = Rx(a) Ry(b) Rz(c)."""
    _, b, c = angles
    ry = quat_to_mat(quat_from_axis_angle((0, 1, 0), b))
    rz = quat_to_mat(quat_from_axis_angle((0, 0, 1), c))
    col_a = rz.T @ ry.T @ np.array([1.0, 0.0, 0.0])
    col_b = rz.T @ np.array([0.0, 1.0, 0.0])
    col_c = np.array([0.0, 0.0, 1.0])
    return np.stack([col_a, col_b, col_c], axis=1)
