"""Tier 1: links, joints, DoF, joint types, axes, limits, names and parent relations."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from loader.model import mj

from .. import sapien_side
from ..data_pool import borrowed
from ..reference import limits_disabled
from ..report import Metric, TierReport, judged, metric
from ..sampling import direction_angle
from ..tolerances import Tolerances

_JT = mujoco.mjtJoint
KIND = {
    int(_JT.mjJNT_FREE): "free",
    int(_JT.mjJNT_BALL): "ball",
    int(_JT.mjJNT_SLIDE): "slide",
    int(_JT.mjJNT_HINGE): "hinge",
}
SAPIEN_TYPES = {
    "hinge": {"revolute", "revolute_unwrapped", "continuous"},
    "slide": {"prismatic"},
    "ball": {"revolute", "revolute_unwrapped", "continuous"},
}
_MAX_NOTES = 25


def _link_index(result) -> dict[tuple[int, int], int]:
    """(articulation, link) -> MuJoCo body carried there."""
    out = {}
    for b, entry in enumerate(result.mapping.bodies):
        if entry is not None and entry.articulation is not None and entry.link is not None:
            out[(entry.articulation, entry.link)] = b
    return out


def _sapien_parent_body(result, body: int, carried: dict) -> int:
    """The nearest ancestor link that carries a body (helper links skipped); 0 (world) at the root."""
    entry = result.mapping.bodies[body]
    art = result.articulations[entry.articulation]
    link = art.links[entry.link].parent
    while link is not None:
        b = carried.get((entry.articulation, link.index))
        if b is not None:
            return b
        link = link.parent
    return 0


def _mujoco_parent_body(result, model, body: int) -> int:
    """The nearest ancestor body carried by a link; 0 when only static bodies lie between it and the world."""
    parent = model.body_parentid[body]
    while parent != 0 and sapien_side.body_link(result, parent) is None:
        parent = model.body_parentid[parent]
    return int(parent)


def _limit_error(ref: tuple[float, float], got: np.ndarray) -> float:
    errs = []
    for r, g in zip(ref, np.asarray(got, dtype=float).ravel()):
        if np.isinf(r) or np.isinf(g):
            errs.append(0.0 if r == g else np.inf)
        else:
            errs.append(abs(r - g))
    return max(errs)


@dataclass
class _JointChecks:
    """What the joint checks gather: mismatches (after the bodies' ones), the axis, anchor and limit errors, and the
    dofs MuJoCo's joints call for."""

    mismatches: list[str]
    axis_err: list[float] = field(default_factory=list)
    anchor_err: list[float] = field(default_factory=list)
    limit_err: list[float] = field(default_factory=list)
    expected_dofs: int = 0


def structure(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    mismatches: list[str] = []
    with borrowed(model) as data:
        mujoco.mj_kinematics(model, data)
        sapien_side.set_state(result, model.qpos0, np.zeros(model.nv))
        carried = _link_index(result)
        _check_bodies(result, model, carried, mismatches)

        # Joints: kind, DoF count, SAPIEN type, name, axis, anchor, limits.
        checks = _JointChecks(mismatches)
        limits = result.controller.term("rows", on=True)
        limit_rows = limits.rows if limits is not None else {}  # MuJoCo solves their limit rows
        for j in range(model.njnt):
            _check_joint(result, model, data, j, limit_rows, checks)
        sapien_dofs = sum(a.dof for a in result.articulations)
        if sapien_dofs != checks.expected_dofs:
            mismatches.append(
                f"{sapien_dofs} SAPIEN dofs, {checks.expected_dofs} MuJoCo joint dofs (free joints excluded)"
            )

        notes = mismatches[:_MAX_NOTES] + (
            [f"... {len(mismatches) - _MAX_NOTES} more"] if len(mismatches) > _MAX_NOTES else []
        )
        metrics = [
            Metric(
                "mismatches", float(len(mismatches)), float(len(mismatches)), 0.0, "count", model.nbody + model.njnt
            ),
            metric("axis", checks.axis_err, tolerances["structure.axis"], "rad"),
            metric("anchor", checks.anchor_err, tolerances["structure.anchor"], "m"),
            metric("limit", checks.limit_err, tolerances["structure.limit"], "rad or m"),
        ]
        return judged(
            "structure",
            metrics,
            notes,
            settings={
                "bodies": model.nbody - 1,
                "joints": model.njnt,
                "dofs": sapien_dofs,
                "links": sum(len(a.links) for a in result.articulations),
            },
        )


def _check_bodies(result, model: mujoco.MjModel, carried: dict, mismatches: list[str]) -> None:
    """Bodies: every body below a joint must be carried by a link, named like the body, under the right parent."""
    moving = np.zeros(model.nbody, dtype=bool)
    for b in range(1, model.nbody):
        moving[b] = model.body_jntnum[b] > 0 or moving[model.body_parentid[b]]
    for b in range(1, model.nbody):
        link = sapien_side.body_link(result, b)
        if link is None:
            if moving[b]:
                mismatches.append(f"moving body {mj.name(model, 'body', b)!r} has no link")
            continue
        body_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
        if body_name and link.name != body_name:
            mismatches.append(f"body {body_name!r} is carried by link named {link.name!r}")
        sp, ref = _sapien_parent_body(result, b, carried), _mujoco_parent_body(result, model, b)
        if sp != ref:
            mismatches.append(
                f"body {mj.name(model, 'body', b)!r}: parent "
                f"{mj.name(model, 'body', sp)!r} in SAPIEN, "
                f"{mj.name(model, 'body', ref)!r} in MuJoCo"
            )


def _check_joint(
    result, model: mujoco.MjModel, data: mujoco.MjData, j: int, limit_rows: dict, checks: _JointChecks
) -> None:
    """One joint: its kind and DoF count in the mapping, the SAPIEN joint types, and for hinges and slides the
    name, axis, anchor and limits."""
    kind = KIND[int(model.jnt_type[j])]
    name = mj.name(model, "joint", j)
    entry = result.mapping.joints[j] if j < len(result.mapping.joints) else None
    if entry is None:
        checks.mismatches.append(f"joint {name!r} ({kind}) is not in the mapping")
        return
    if entry.kind != kind:
        checks.mismatches.append(f"joint {name!r}: kind {entry.kind!r} in SAPIEN, {kind!r} in MuJoCo")
        return
    want = {"hinge": 1, "slide": 1, "ball": 3, "free": 0}[kind]
    checks.expected_dofs += want
    if len(entry.dofs) != want:
        checks.mismatches.append(f"joint {name!r}: {len(entry.dofs)} SAPIEN dofs, expected {want}")
        return
    art = result.articulations[entry.articulation]
    if kind == "free":
        return
    joints = [art.active_joints[d] for d in entry.dofs]
    for joint in joints:
        if joint.type not in SAPIEN_TYPES[kind]:
            checks.mismatches.append(f"joint {name!r}: SAPIEN type {joint.type!r} for a MuJoCo {kind}")
    if kind == "ball":
        return
    joint = joints[0]
    if mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) and joint.name != name:
        checks.mismatches.append(f"joint {name!r} is named {joint.name!r} in SAPIEN")
    _check_joint_frame(data, j, kind, joint, checks)
    _check_joint_limits(model, j, name, joint, limit_rows.get((entry.articulation, entry.dofs[0])), checks)


def _check_joint_frame(data: mujoco.MjData, j: int, kind: str, joint, checks: _JointChecks) -> None:
    """A hinge's or slide's axis, and a hinge's anchor (its offset across the axis), against MuJoCo's."""
    frame = joint.get_global_pose().to_transformation_matrix()
    axis = frame[:3, 0]
    checks.axis_err.append(direction_angle(axis, data.xaxis[j]))
    if kind == "hinge":
        offset = frame[:3, 3] - data.xanchor[j]
        checks.anchor_err.append(np.linalg.norm(offset - np.dot(offset, data.xaxis[j]) * data.xaxis[j]))


def _check_joint_limits(model: mujoco.MjModel, j: int, name: str, joint, soft, checks: _JointChecks) -> None:
    """A hinge's or slide's limits against MuJoCo's enforced range: the ends of its soft limit rows (`soft`, with
    PhysX's hard limit beyond them) where it has some, PhysX's limit otherwise."""
    enforced = model.jnt_limited[j] and not limits_disabled(model)
    ref = tuple(model.jnt_range[j]) if enforced else (-np.inf, np.inf)
    if soft is not None:  # MuJoCo's soft limit rows (loader/runtime/rows.py): their ends are the range,
        checks.limit_err.append(_limit_error(ref, (soft.lower, soft.upper)))  # and PhysX's hard limit lies beyond
        low, high = np.asarray(joint.limit, dtype=float).ravel()
        if not ((low < ref[0] or np.isinf(ref[0])) and (high > ref[1] or np.isinf(ref[1]))):  # inf: an open end
            checks.mismatches.append(
                f"joint {name!r}: PhysX's limit {low:.6g}..{high:.6g} does not clear the soft "
                f"limit rows at {ref[0]:.6g}..{ref[1]:.6g}"
            )
    else:
        checks.limit_err.append(_limit_error(ref, joint.limit))
