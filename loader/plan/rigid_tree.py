"""An articulation's rigid-body tree as PhysX holds it, as flat arrays, read once from the built articulation for a
law that computes its joint-space inertia M and bias c each step over (env, DoF) with no SAPIEN or MuJoCo call
(`loader/maniskill/inertia.py`).

Per link: its parent, the joint that carries it (fixed, revolute or prismatic, one DoF at most: the loader gives
every link one joint), that joint's frame in the parent link at zero and the link's frame in the joint, and the
link's mass, centre of mass and inertia tensor in its own frame; per DoF, its link and its armature. SAPIEN's joints
turn about, or slide along, their frame's x axis, and the articulation's DoFs are its joints with a DoF, in order.
PhysX's articulation adds each joint's armature to M's diagonal, as MuJoCo does
(tests/test_maniskill_inertia.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sapien

from ..model.frames import quat_to_mat

FIXED, REVOLUTE, PRISMATIC = 0, 1, 2
KINDS = {"fixed": FIXED, "revolute": REVOLUTE, "revolute_unwrapped": REVOLUTE, "prismatic": PRISMATIC}


@dataclass
class RigidTree:
    """The tree's numbers (PhysX's float32 values, widened); links in the articulation's order, parents first."""

    parent: np.ndarray  # (nlink,): the parent link, -1 for the root
    kind: np.ndarray  # (nlink,): the joint carrying the link: FIXED, REVOLUTE or PRISMATIC (the root's: FIXED)
    dof: np.ndarray  # (nlink,): the DoF of that joint, -1 where it has none
    joint_position: np.ndarray  # (nlink, 3): the joint's frame in its parent link
    joint_rotation: np.ndarray  # (nlink, 3, 3)
    link_position: np.ndarray  # (nlink, 3): the link's frame in the joint's frame
    link_rotation: np.ndarray  # (nlink, 3, 3)
    mass: np.ndarray  # (nlink,)
    centre: np.ndarray  # (nlink, 3): the centre of mass in the link's frame
    inertia: np.ndarray  # (nlink, 3, 3): the inertia tensor about it, in the link's frame
    armature: np.ndarray  # (ndof,)
    link_of_dof: np.ndarray  # (ndof,): the link each DoF's joint carries
    ancestors: np.ndarray  # (nlink, ndof): whether DoF j moves link i (j's link is i or above it)
    depth: int  # the most joints between the root and a link
    floating: bool  # the root moves freely (six more coordinates: its centre's velocity, its angular velocity)


def rigid_tree(articulation: sapien.physx.PhysxArticulation, floating: bool | None = None) -> RigidTree:
    """The tree of a built articulation (`floating`: whether its root moves; None: as its root link says)."""
    links = list(articulation.links)
    index = {id(link): i for i, link in enumerate(links)}
    n = len(links)
    parent, kind, dof = np.full(n, -1), np.zeros(n, dtype=int), np.full(n, -1)
    joint_position, joint_rotation = np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1))
    link_position, link_rotation = np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1))
    armature, link_of_dof, root_joint = [], [], "fixed"
    for joint in articulation.joints:
        child = index[id(joint.child_link)]
        if joint.parent_link is None:
            root_joint = joint.type  # "fixed" where the root is fixed
            continue
        parent[child] = index[id(joint.parent_link)]
        if parent[child] >= child:
            raise ValueError(f"link {joint.child_link.name!r} comes before its parent: the tree takes parents first")
        kind[child] = KINDS.get(joint.type, -1)
        if kind[child] < 0:
            raise ValueError(f"joint {joint.name!r} is a {joint.type} joint: the tree takes fixed, revolute, prismatic")
        joint_position[child], joint_rotation[child] = joint.pose_in_parent.p, quat_to_mat(joint.pose_in_parent.q)
        inverse = joint.pose_in_child.inv()
        link_position[child], link_rotation[child] = inverse.p, quat_to_mat(inverse.q)
        if joint.dof:
            dof[child] = len(link_of_dof)
            link_of_dof.append(child)
            armature.append(float(np.asarray(joint.armature).reshape(-1)[0]))
    mass = np.array([float(link.mass) for link in links])
    centre = np.array([np.asarray(link.cmass_local_pose.p, np.float64) for link in links]).reshape(n, 3)
    inertia = np.zeros((n, 3, 3))
    for i, link in enumerate(links):
        principal = quat_to_mat(link.cmass_local_pose.q)
        inertia[i] = principal @ np.diag(np.asarray(link.inertia, np.float64)) @ principal.T
    link_of_dof = np.array(link_of_dof, dtype=int)
    ancestors = np.zeros((n, link_of_dof.size), dtype=bool)
    depth = np.zeros(n, dtype=int)
    for i in range(n):  # parents come first
        if parent[i] >= 0:
            ancestors[i] = ancestors[parent[i]]
            depth[i] = depth[parent[i]] + 1
        if dof[i] >= 0:
            ancestors[i, dof[i]] = True
    if floating is None:
        floating = root_joint != "fixed"
    return RigidTree(
        parent,
        kind,
        dof,
        joint_position,
        joint_rotation,
        link_position,
        link_rotation,
        mass,
        centre,
        inertia,
        np.array(armature, dtype=np.float64),
        link_of_dof,
        ancestors,
        int(depth.max(initial=0)),
        bool(floating),
    )


def turning_slides(tree: RigidTree) -> np.ndarray:
    """(ndof,): the slides whose link can turn (a hinge above them, or a floating root): PhysX's drive measures their
    velocity short of the centripetal term (docs/mapping.md#slides-on-turning-links), so they keep no drive."""
    slides = tree.kind[tree.link_of_dof] == PRISMATIC
    hinges = tree.kind[tree.link_of_dof] == REVOLUTE
    above = tree.ancestors[tree.link_of_dof] & ~np.eye(tree.link_of_dof.size, dtype=bool)  # (DoF, the DoFs above)
    return slides & (tree.floating | (above & hinges[None, :]).any(axis=1))
