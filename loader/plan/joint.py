"""MuJoCo joints onto PhysX articulation joints.

SAPIEN joints act along +X of the joint frame. A hinge or slide becomes one revolute or prismatic joint whose
frame has +X on the MuJoCo axis; `ref` is folded into the parent-side frame so that SAPIEN's q equals MuJoCo's q.
A ball becomes three revolute joints about the body's x, y and z axes (intrinsic XYZ angles). A free joint is a
floating root and gets no joint here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from ..errors import Notes
from ..model import mj
from ..model.frames import pose, quat_from_axis_angle, quat_x_to
from ..model.joints import FREE, HINGE, SLIDE, closed_range, dof_damping, is_limited, joint_stiffness


@dataclass
class JointPlan:
    """The incoming joint of one SAPIEN link."""

    type: str  # "fixed", "revolute", "revolute_unwrapped", "prismatic" or "undefined" (floating root)
    name: str = ""
    limits: tuple[float, float] = (-np.inf, np.inf)
    # joint frame as seen from the child link; the parent-side frame is completed by the tree planner
    frame_in_child: sapien.Pose = field(default_factory=sapien.Pose)
    # rotation/translation that maps the reference configuration to SAPIEN's q = 0
    ref_offset: sapien.Pose = field(default_factory=sapien.Pose)
    damping: float = 0.0
    armature: float = 0.0
    stiffness: float = 0.0
    spring_target: float = 0.0
    mj_joint: int | None = None
    ball_axis: int | None = None  # 0, 1, 2 for the three revolutes of a ball joint


def plan_joint(model: mujoco.MjModel, j: int, notes: Notes) -> list[JointPlan]:
    """One MuJoCo joint as the chain of SAPIEN joints that reproduces it (empty for a free joint)."""
    jtype = int(model.jnt_type[j])
    name = mj.name(model, "joint", j)
    anchor = model.jnt_pos[j].copy()
    dof = model.jnt_dofadr[j]
    damping = dof_damping(model, dof)
    armature = float(model.dof_armature[dof])
    stiffness = joint_stiffness(model, j)
    if jtype == FREE:
        if stiffness > 0:  # damping and armature: `runtime/free_joint.py`
            notes.drop(
                "joint",
                name,
                f"free joint stiffness {stiffness:g} dropped: a PhysX floating root has no joint to carry it",
            )
        return []
    if jtype in (HINGE, SLIDE):
        limited = is_limited(model, j) and not mj.disabled(model, "limit", "constraint")
        limits_held = closed_range(*(float(x) for x in model.jnt_range[j])) if limited else (-np.inf, np.inf)
        ref = float(model.qpos0[model.jnt_qposadr[j]])
        axis = model.jnt_axis[j]
        if jtype == HINGE:
            kind = "revolute_unwrapped"  # limited too: PhysX's "revolute" wraps q past 2 pi into a far-off limit
            ref_offset = pose((0, 0, 0), quat_from_axis_angle((1, 0, 0), -ref))
        else:
            kind = "prismatic"
            ref_offset = pose((-ref, 0, 0))
        spring_target = float(model.qpos_spring[model.jnt_qposadr[j]]) if stiffness else 0.0  # MuJoCo: no spring
        return [
            JointPlan(
                kind,
                name,
                limits_held,
                pose(anchor, quat_x_to(axis)),
                ref_offset,
                damping,
                armature,
                stiffness,
                spring_target,
                j,
            )
        ]
    # ball: three revolutes about x, y, z of the body frame at the anchor
    if model.jnt_limited[j]:
        notes.drop("joint", name, "ball joint cone limit not mapped: three revolutes cannot express a cone")
    notes.approximate(
        "joint",
        name,
        "ball joint as three revolutes integrated in Euler angles: MuJoCo integrates "
        "the body-frame angular velocity, so velocities agree to O(timestep x speed^2)",
    )
    if stiffness > 0:
        notes.drop("joint", name, "ball joint stiffness not mapped")
    if damping > 0 or armature > 0:
        notes.approximate(
            "joint",
            name,
            "ball joint damping/armature applied per Euler angle: MuJoCo applies "
            "them to the body-frame angular velocity, which differs away from the zero rotation",
        )
    return [
        JointPlan(
            "revolute_unwrapped",
            f"{name}_{'xyz'[i]}",
            (-np.inf, np.inf),
            pose(anchor, quat_x_to(axis)),
            sapien.Pose(),
            dof_damping(model, dof + i),
            float(model.dof_armature[dof + i]),
            0.0,
            0.0,
            j,
            i,
        )
        for i, axis in enumerate(np.eye(3))
    ]
