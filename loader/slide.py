"""Slide joints on turning links: the velocity a PhysX prismatic drive acts on, put back to MuJoCo's qdot.

Measured: PhysX's drive on a prismatic joint acts on the joint's end-of-step velocity less dt k, where
k = (w x (w x d)) . a, w is the parent's angular velocity, d the child's centre of mass less the parent's and a the
joint's axis, all at the start of the step: the centripetal acceleration of the child's centre of mass about the
parent's along the axis, which the drive row (taken on the two centres of mass with the step's start geometry)
does not see. The joint's own motion is right (no drive: float32 agreement); a damped slide on a turning link is
not: a 15 g finger with damping 1 on a hand turning at 2 rad/s, 0.1 m from the hand's centre of mass, is 1.4e-5
m/s off MuJoCo after one step, as dt^2 D w^2 d / (m + armature + dt D) says (panda and aloha grippers at 2 rad/s
joint speeds: up to 1e-3 and 7e-3 m/s). PhysX's source agrees: a drive row measures the joint's velocity from the
two links' spatial velocities (at their centres of mass, rows taken at the start of the step), and its unconstrained
step has added dt times each link's velocity-product acceleration to them, of which w x (w x d) lies along a slide's
axis. A revolute drive does not see it (its row is angular: the drift's angular part w x axis qdot is normal to the
axis).
`set_ctrl` therefore adds dt k to the drive's velocity target and dt^2 k to its position target every step
(`drive.apply`), which puts the drive's force back to MuJoCo's (K dt + D) qdot form: one-step errors drop to
float32 (panda 1.0e-3 -> 4e-7, aloha 6.6e-3 -> 1e-6 m/s). A drive set by the caller after `release()` keeps the
offset; it is second order in dt.
The connect rows of `connect.py` carry the same term for a D6's linear drives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frames import cross


@dataclass(frozen=True)
class SlideDrive:
    """A prismatic DoF whose parent link can turn: its links and the constants of its drive's offset."""

    articulation: int
    dof: int
    joint: object  # sapien.physx.PhysxArticulationJoint
    parent: object  # sapien.physx.PhysxArticulationLinkComponent
    child: object
    axis_in_parent: np.ndarray  # the joint's axis (the joint frame's +X) in the parent link's frame

    def centripetal(self) -> float:
        """k = (w x (w x d)) . a at the links' current state (m/s^2)."""
        parent_pose = self.parent.entity_pose
        rotation = parent_pose.to_transformation_matrix()[:3, :3]
        omega = np.asarray(self.parent.angular_velocity, dtype=np.float64)
        d = (self.child.entity_pose * self.child.cmass_local_pose).p - (parent_pose * self.parent.cmass_local_pose).p
        return float(cross(omega, cross(omega, d)) @ (rotation @ self.axis_in_parent))


def can_turn(link, articulation) -> bool:
    """Whether a revolute joint or a floating root lies between `link` and the world (a planar root's slides on a
    fixed base do not turn)."""
    while link is not None and not link.is_root:
        if link.joint.type in ("revolute", "revolute_unwrapped"):
            return True
        link = link.parent
    return articulation.root.joint.type != "fixed"


def map_slides(articulations) -> list[SlideDrive]:
    """Every prismatic DoF whose parent link can turn."""
    slides = []
    for a, articulation in enumerate(articulations):
        for dof, joint in enumerate(articulation.active_joints):
            parent = joint.parent_link
            if joint.type != "prismatic" or parent is None or not can_turn(parent, articulation):
                continue
            axis = (joint.pose_in_parent.to_transformation_matrix()[:3, 0]).astype(np.float64)
            slides.append(SlideDrive(a, dof, joint, parent, joint.child_link, axis))
    return slides


def drive_offsets(slides: list[SlideDrive], timestep: float) -> dict[tuple[int, int], float]:
    """(articulation, dof) -> dt k, the velocity the DoF's drive is short of this step."""
    return {(s.articulation, s.dof): timestep * s.centripetal() for s in slides}
