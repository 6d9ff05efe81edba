"""Slide joints on turning links: PhysX's prismatic drive misses the centripetal acceleration of the child's
centre of mass along the axis, so `set_ctrl` adds dt k to its velocity target and dt^2 k to its position target
every step. Derivation: docs/mapping.md#slides-on-turning-links.
"""

from __future__ import annotations

from dataclasses import dataclass

import sapien

from .term import Compilation, Term


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
        frame."""
        return self.centripetal_from(*parent_motion(self.parent))

    def centripetal_from(self, to_parent: sapien.Pose, w) -> float:
        """`centripetal` with the parent's inverse pose and its angular velocity in its frame already read (plain
        floats: numpy's per-call cost would dominate three-vectors)."""
        d = (to_parent * self.child.entity_pose * self.child_com).p
        a, c = self.axis_in_parent, self.parent_com
        dx, dy, dz = d[0] - c[0], d[1] - c[1], d[2] - c[2]
        wd = w[0] * dx + w[1] * dy + w[2] * dz
        wa = w[0] * a[0] + w[1] * a[1] + w[2] * a[2]
        ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
        return float(wd * wa - ww * (dx * a[0] + dy * a[1] + dz * a[2]))


def parent_motion(parent) -> tuple[sapien.Pose, object]:
    """A parent link's inverse pose and its angular velocity in its own frame."""
    to_parent = parent.entity_pose.inv()
    return to_parent, (sapien.Pose(q=to_parent.q) * sapien.Pose(parent.angular_velocity)).p


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
            slides.append(
                SlideDrive(a, dof, joint, parent, joint.child_link, axis, com, joint.child_link.cmass_local_pose)
            )
    return slides


def drive_offsets(slides: list[SlideDrive], timestep: float) -> list[float]:
    """Per slide, dt k: the velocity its drive is short of this step (each parent read once)."""
    parents: dict[int, tuple] = {}
    out = []
    for s in slides:
        motion = parents.get(id(s.parent))
        if motion is None:
            motion = parents[id(s.parent)] = parent_motion(s.parent)
        out.append(timestep * s.centripetal_from(*motion))
    return out


class SlideTerm(Term):
    """Every step, the velocity each turning slide's drive is short of joins its drive's targets."""

    name = "slides"

    def __init__(self, slides: list[SlideDrive]):
        self.slides = slides

    def compile(self, compilation: Compilation) -> None:
        self.drive = compilation.layout.drive_of([(s.articulation, s.dof) for s in self.slides])

    def contribute(self, step) -> None:
        offsets = step.law[6]
        offsets[self.drive] = drive_offsets(self.slides, step.timestep)

    def velocity_links(self, articulations) -> list:
        return [s.parent for s in self.slides]
