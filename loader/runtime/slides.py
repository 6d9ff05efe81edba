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
float32 (panda 1.0e-3 -> 4e-7, aloha 6.6e-3 -> 1e-6 m/s). A drive the caller sets after `release()` goes without
the offset: second order in dt per step.
The connect rows of `connect.py` carry the same term for a D6's linear drives.
"""

from __future__ import annotations

from dataclasses import dataclass

import sapien


@dataclass(frozen=True)
class SlideDrive:
    """A prismatic DoF whose parent link can turn: its links and the constants of its drive's offset."""

    articulation: int
    dof: int
    joint: object  # sapien.physx.PhysxArticulationJoint
    parent: object  # sapien.physx.PhysxArticulationLinkComponent
    child: object
    axis_in_parent: tuple[float, float, float]  # the joint's axis (the joint frame's +X) in the parent link's frame
    parent_com: tuple[float, float, float]  # the parent's centre of mass in its frame
    child_com: sapien.Pose  # the child's centre of mass in its frame

    def centripetal(self) -> float:
        """k = (w x (w x d)) . a = (w.d)(w.a) - (w.w)(d.a) at the links' current state (m/s^2), all in the parent's
        frame (plain floats: numpy's per-call cost would dominate three-vectors)."""
        to_parent = self.parent.entity_pose.inv()
        d = (to_parent * self.child.entity_pose * self.child_com).p
        w = (sapien.Pose(q=to_parent.q) * sapien.Pose(self.parent.angular_velocity)).p
        a, c = self.axis_in_parent, self.parent_com
        dx, dy, dz = d[0] - c[0], d[1] - c[1], d[2] - c[2]
        wd = w[0] * dx + w[1] * dy + w[2] * dz
        wa = w[0] * a[0] + w[1] * a[1] + w[2] * a[2]
        ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        return float(wd * wa - ww * (dx * a[0] + dy * a[1] + dz * a[2]))


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
            axis = tuple(float(x) for x in joint.pose_in_parent.to_transformation_matrix()[:3, 0])
            com = tuple(float(x) for x in parent.cmass_local_pose.p)
            slides.append(SlideDrive(a, dof, joint, parent, joint.child_link, axis, com, joint.child_link.cmass_local_pose))
    return slides


def drive_offsets(slides: list[SlideDrive], timestep: float) -> dict[tuple[int, int], float]:
    """(articulation, dof) -> dt k, the velocity the DoF's drive is short of this step."""
    return {(s.articulation, s.dof): timestep * s.centripetal() for s in slides}


@dataclass
class SlideTerm:
    """Every step, the velocity each turning slide's drive is short of joins its drive's targets."""

    slides: list[SlideDrive]
    name: str = "slides"

    def contribute(self, step) -> None:
        step.offsets = drive_offsets(self.slides, step.timestep)

    def velocity_links(self, articulations) -> list:
        return [s.parent for s in self.slides]
