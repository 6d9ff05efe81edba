"""MuJoCo's joint kinds as the loader names them, and the passive numbers of one joint as MuJoCo applies them."""

from __future__ import annotations

import math

import mujoco

from . import mj

HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
BALL = int(mujoco.mjtJoint.mjJNT_BALL)
FREE = int(mujoco.mjtJoint.mjJNT_FREE)
KIND = {HINGE: "hinge", SLIDE: "slide", BALL: "ball", FREE: "free"}
DRIVEN = ("hinge", "slide")  # the kinds whose one DoF is a PhysX drive (a "drive DoF")
OPEN_END = 1e4  # rad or m beyond a range's finite end: where PhysX's limit stands for an end MuJoCo leaves open


def mujoco_coordinates(model: mujoco.MjModel) -> bool:
    """Whether every joint SAPIEN steps has MuJoCo's coordinates (no ball joint: SAPIEN's three angles are not
    MuJoCo's), so that MuJoCo's joint-space inertia is PhysX's."""
    return not any(int(t) == BALL for t in model.jnt_type)


def is_limited(model: mujoco.MjModel, j: int) -> bool:
    """Whether anything limits the joint: MuJoCo limits it and its range is not open at both ends (a wheel's
    `range="-inf inf"` is an unlimited joint)
    (tests/test_loader_limit.py::test_an_open_range_end_limits_one_side_only)."""
    return bool(model.jnt_limited[j]) and not all(math.isinf(float(x)) for x in model.jnt_range[j])


def closed_range(lower: float, upper: float) -> tuple[float, float]:
    """A range as PhysX's limit holds it: an open (infinite) end stands `OPEN_END` beyond the finite one, since
    PhysX cannot switch a joint in a scene between limited and free, and the rows widen a finite limit."""
    return (upper - OPEN_END if math.isinf(lower) else lower, lower + OPEN_END if math.isinf(upper) else upper)


def joint_stiffness(model: mujoco.MjModel, j: int) -> float:
    return float(model.jnt_stiffness[j]) if not mj.disabled(model, "spring") else 0.0


def dof_damping(model: mujoco.MjModel, dof: int) -> float:
    return float(model.dof_damping[dof]) if not mj.disabled(model, "damper") else 0.0
