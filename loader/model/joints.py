"""MuJoCo's joint kinds as the loader names them, and the passive numbers of one joint as MuJoCo applies them."""

from __future__ import annotations

import mujoco

from . import mj

HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
BALL = int(mujoco.mjtJoint.mjJNT_BALL)
FREE = int(mujoco.mjtJoint.mjJNT_FREE)
KIND = {HINGE: "hinge", SLIDE: "slide", BALL: "ball", FREE: "free"}
DRIVEN = ("hinge", "slide")  # the kinds whose one DoF is a PhysX drive (a "drive DoF")


def mujoco_coordinates(model: mujoco.MjModel) -> bool:
    """Whether every joint SAPIEN steps has MuJoCo's coordinates (no ball joint: SAPIEN's three angles are not
    MuJoCo's), so that MuJoCo's joint-space inertia is PhysX's."""
    return not any(int(t) == BALL for t in model.jnt_type)


def joint_stiffness(model: mujoco.MjModel, j: int) -> float:
    return float(model.jnt_stiffness[j]) if not mj.disabled(model, "spring") else 0.0


def dof_damping(model: mujoco.MjModel, dof: int) -> float:
    return float(model.dof_damping[dof]) if not mj.disabled(model, "damper") else 0.0
