"""Equality constraints: joint and tendon couplings, and connects and welds that move only hinges, slides and free
joints, as MuJoCo's own rows (`runtime/rows.py` asks MuJoCo for their force every step); connects and welds that
move a ball joint as PhysX D6 joints that `runtime/equalities.py` drives with MuJoCo's soft row every step.
Derivation: docs/mapping.md#equalities.
"""

from __future__ import annotations

import mujoco
import numpy as np
import sapien

from ..errors import Notes
from ..model import mj
from ..model.equalities import D6Joint, EqualityLink
from ..model.mapping import Mapping
from ..model.soft_row import SoftRow, diag_approx
from .physx_settings import scene_timestep

EQ = mujoco.mjtEq


def map_equalities(
    model: mujoco.MjModel, scene: sapien.Scene, articulations, mapping: Mapping, notes: Notes
) -> list[EqualityLink]:
    result = []
    if mj.disabled(model, "equality", "constraint"):
        return result  # MuJoCo enforces none of them (<flag equality/constraint="disable"/>)
    at_qpos0 = []  # MuJoCo's forward pass at qpos0 with every equality on, made once (effective masses, diagApprox)

    def qpos0_data() -> mujoco.MjData:
        if not at_qpos0:
            at_qpos0.append(mj.forward_at(model, all_equalities=True))
        return at_qpos0[0]

    for e in range(model.neq):
        name = mj.name(model, "equality", e)
        etype = int(model.eq_type[e])
        if etype in (int(EQ.mjEQ_JOINT), int(EQ.mjEQ_TENDON)):
            result.append(_coupling(model, e, name, mapping, notes))
        elif etype in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)) and _joint_row(model, mapping, e):
            # MuJoCo's rows while set_ctrl runs; the D6 built beside them stands by and locks at release()
            standby = _d6(model, e, name, scene, articulations, mapping, Notes(), qpos0_data).joint
            result.append(EqualityLink(name, "MuJoCo row", True, joint=standby, index=e))
        elif etype in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
            result.append(_d6(model, e, name, scene, articulations, mapping, notes, qpos0_data))
        else:
            reason = f"equality type {EQ(etype).name.removeprefix('mjEQ_').lower()} has no PhysX equivalent"
            notes.drop("equality", name, reason)
            result.append(EqualityLink(name, "", False, reason, index=e))
    return result


def _joint_row(model: mujoco.MjModel, mapping: Mapping, e: int) -> bool:
    """Whether a connect or weld moves only hinges, slides and free joints (a fixed-base loop, an arm welded to a
    fixed or mocap body, a floating body welded to an arm): then its rows are MuJoCo's own, solved with the limits
    and couplings next to them, and their force is joint forces and, on a free joint, a wrench on its root link
    (`runtime/integrated.py`). A ball joint in the loop makes it a D6 joint."""
    bodies = [int(model.eq_obj1id[e]), int(model.eq_obj2id[e])]
    if int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
        bodies = [int(model.site_bodyid[s]) for s in bodies]
    moved = mj.body_dofs(model, bodies[0]) | mj.body_dofs(model, bodies[1])
    return bool(moved) and all(
        mapping.joints[int(model.dof_jntid[d])].kind in ("hinge", "slide", "free") for d in moved
    )


def _coupling(model, e, name, mapping, notes) -> EqualityLink:
    """obj1 = poly(obj2) between joints or fixed tendons: MuJoCo's row, mapped when every joint it moves is a
    hinge or slide (its force is then a joint force SAPIEN can apply)."""
    etype = int(model.eq_type[e])
    objects = [int(model.eq_obj1id[e])] + ([int(model.eq_obj2id[e])] if model.eq_obj2id[e] >= 0 else [])
    for obj in objects:
        joints = [(obj, 1.0)] if etype == int(EQ.mjEQ_JOINT) else mj.fixed_tendon_terms(model, obj)
        if not joints:
            reason = "couples a spatial tendon, whose force SAPIEN's joints cannot take"
        elif any(mapping.joints[joint].drive_key is None for joint, _ in joints):
            reason = "couples a ball or free joint"
        else:
            continue
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason, index=e)
    return EqualityLink(name, "MuJoCo row", True, index=e)


def _d6(model, e, name, scene, articulations, mapping, notes, qpos0_data) -> EqualityLink:
    """connect: the two anchor points coincide (translation locked); weld: the relative pose is held too."""
    timestep = scene_timestep(scene, model)
    if int(model.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
        reason = "site-based connect/weld is not mapped"
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason, index=e)
    body1, body2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])

    def component(body):
        target = mapping.bodies[body]
        if target.articulation is None:
            return None
        return articulations[target.articulation].links[target.link]

    etype = int(model.eq_type[e])
    if etype == int(EQ.mjEQ_CONNECT):
        frame1 = sapien.Pose(model.eq_data[e][0:3])  # the anchor in body1's frame
        frame2 = sapien.Pose(model.eq_data[e][3:6])  # the same point in body2's frame at qpos0
    else:
        # weld: body2's anchor held at `relpose` (which includes the anchor) in body1's frame
        relative_quat = model.eq_data[e][6:10]
        if np.linalg.norm(relative_quat) > 0:
            frame1 = sapien.Pose(model.eq_data[e][3:6], relative_quat / np.linalg.norm(relative_quat))
        else:
            data = qpos0_data()
            frame1 = (
                sapien.Pose(data.xpos[body1], data.xquat[body1]).inv()
                * sapien.Pose(data.xpos[body2], data.xquat[body2])
                * sapien.Pose(model.eq_data[e][0:3])
            )
        frame2 = sapien.Pose(model.eq_data[e][0:3])  # MuJoCo's weld anchor, in body2's frame
    world = qpos0_data()  # its body poses: qpos0's

    def end(body, frame):  # (link, frame in the body, body, the body's world pose if it does not move)
        return component(body), frame, body, sapien.Pose(world.xpos[body], world.xquat[body])

    ends = [end(body1, frame1), end(body2, frame2)]
    rows = diag_approx(model, qpos0_data(), int(mujoco.mjtConstraint.mjCNSTR_EQUALITY), e)
    if not len(rows) or (ends[0][0] is None and ends[1][0] is None):  # MuJoCo makes no rows for it
        reason = "joins two bodies fixed to the world: it constrains no degree of freedom"
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason, index=e)
    if ends[1][0] is None:  # SAPIEN takes the world (None) only as the first end
        ends.reverse()
    (parent, parent_frame, parent_body, parent_pose), (child, child_frame, child_body, _) = ends
    drive = scene.create_drive(
        parent, parent_frame if parent is not None else parent_pose * parent_frame, child, child_frame
    )
    weld = etype == int(EQ.mjEQ_WELD)
    extra = (
        {
            "relative_quat": np.asarray(frame1.q, dtype=float),
            "torquescale": float(model.eq_data[e][10]),
            "child_is_body1": child_body == body1,
        }
        if weld
        else {}
    )
    joint = D6Joint(
        drive,
        child,
        np.asarray(child_frame.p, dtype=float),
        parent,
        np.asarray(parent_frame.p, dtype=float),
        parent_pose,
        sapien.Pose(q=parent_frame.q),
        SoftRow.of(model, model.eq_solref[e], model.eq_solimp[e], timestep),
        np.asarray(rows, dtype=float),
        e,
        child_body,
        parent_body,
        mapping.bodies[child_body].articulation,
        child_rotation=np.asarray(child_frame.q, dtype=float),
        weld=weld,
        **extra,
    )
    kind = "weld" if weld else "connect"
    notes.approximate(
        "equality",
        name,
        f"{kind} as MuJoCo's soft law (solref, solimp) on a PhysX D6 joint's drives "
        "that set_ctrl updates every step; exact on a closed loop, first order in its violation and "
        "in joint damping off (runtime/equalities.py)",
    )
    return EqualityLink(name, "D6 joint", True, joint=joint, index=e)
