"""The kinematic tree: MuJoCo bodies onto SAPIEN articulations and links.

Every child of the world body, and every body with a free joint, starts an articulation. A body gets one link,
plus one massless helper link for each extra joint DoF it carries (several joints in one body, or the three
revolutes of a ball joint), so that every SAPIEN link carries at most one joint, in MuJoCo's joint order.
A root body with joints hangs from a fixed anchor link at its parent's frame.

`maniskill_names` (`MJCFLoader.maniskill_dialect`) names the links as ManiSkill's own MJCF loader does, for task code
written against it: each tree's root is a link `dummy_root_<i>` (i: the root body's place among the world body's
children), carrying the body by a fixed joint unless the body is a wrapper (no geom, no joint but a free one, one child
body: ManiSkill skips it, and its link takes the root's name), and a body's extra joints ride on `<body>_dummy_<k>`
links (tests/test_maniskill.py::test_names_and_dof_order_match_maniskills_loader).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from ..errors import Notes
from ..model import mj
from ..model.frames import pose
from ..model.joints import FREE
from ..model.mapping import centres
from .joint import JointPlan, plan_joint

# Helper links must have a positive mass for PhysX; this is far below any body MuJoCo would accept.
HELPER_MASS = 1e-8
HELPER_INERTIA = 1e-12
ZERO_MOMENT = HELPER_INERTIA  # what a zero principal moment becomes (PhysX would replace it with 1)


@dataclass
class LinkPlan:
    name: str
    parent: int | None  # index of the parent link in the same articulation
    body: int | None  # the MuJoCo body this link carries; None for helper and anchor links
    joint: JointPlan
    pose_in_parent: sapien.Pose = field(default_factory=sapien.Pose)
    mass: float = HELPER_MASS
    cmass: sapien.Pose = field(default_factory=sapien.Pose)
    inertia: np.ndarray = field(default_factory=lambda: np.full(3, HELPER_INERTIA))


@dataclass
class ArticulationPlan:
    """One kinematic tree. Its name is the model's (`<mujoco model=...>`) where the document holds one tree, else
    its root body's (tests/test_loader_structure.py::test_articulations_are_named_after_the_model_or_their_root)."""

    name: str
    root_body: int
    floating: bool
    root_pose: sapien.Pose
    links: list[LinkPlan] = field(default_factory=list)


@dataclass
class TreePlan:
    articulations: list[ArticulationPlan]
    body_link: dict[int, tuple[int, int]]  # MuJoCo body id -> (articulation index, link index)
    notes: Notes


def _body_inertial(model: mujoco.MjModel, b: int, link: LinkPlan, notes: Notes, centre: np.ndarray) -> None:
    """The body's mass and principal moments as MuJoCo compiled them; PhysX keeps tiny moments, but replaces a zero
    one with 1, so a zero moment gets `ZERO_MOMENT` (listed). `centre`: the link's centre of mass (`centres`)."""
    mass = float(model.body_mass[b])
    if mass > 0:
        link.mass = mass
        moments = model.body_inertia[b].copy()
        if (moments <= 0).any():
            notes.approximate(
                "body",
                mj.name(model, "body", b),
                f"zero principal moment of inertia given {ZERO_MOMENT:g} kg m^2 (PhysX replaces a zero moment with 1)",
            )
        link.inertia = np.where(moments > 0, moments, ZERO_MOMENT)
    link.cmass = pose(centre, model.body_iquat[b])


def plan_tree(model: mujoco.MjModel, fix_root_link: bool = True, maniskill_names: bool = False) -> TreePlan:
    data = mj.forward_at(model, kinematics_only=True)
    notes = Notes()
    centre = centres(model)
    articulations: list[ArticulationPlan] = []
    body_link: dict[int, tuple[int, int]] = {}
    for b in range(1, model.nbody):
        parent = int(model.body_parentid[b])
        joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        has_free = any(model.jnt_type[j] == FREE for j in joints)
        name = mj.name(model, "body", b)
        subs = [sub for j in joints for sub in plan_joint(model, j, notes)]
        if has_free or parent not in body_link:
            world = pose(data.xpos[b], data.xquat[b])
            root_type = "fixed" if fix_root_link else "undefined"
            a = len(articulations)
            if has_free or not subs:
                art = ArticulationPlan(name, b, floating=has_free or not fix_root_link, root_pose=world)
                art.links.append(LinkPlan(name, None, b, JointPlan("undefined" if has_free else root_type)))
                _body_inertial(model, b, art.links[-1], notes, centre[b])
                articulations.append(art)
                body_link[b] = (a, 0)
                continue
            anchor_pose = pose(data.xpos[parent], data.xquat[parent])
            art = ArticulationPlan(name, b, floating=not fix_root_link, root_pose=anchor_pose)
            art.links.append(LinkPlan(f"{name}:anchor", None, None, JointPlan(root_type)))
            articulations.append(art)
            parent_index = 0
        else:
            a, parent_index = body_link[parent]
            art = articulations[a]
        relative = pose(model.body_pos[b], model.body_quat[b])
        if not subs:
            link = LinkPlan(name, parent_index, b, JointPlan("fixed"), pose_in_parent=relative)
            _body_inertial(model, b, link, notes, centre[b])
            art.links.append(link)
        for k, sub in enumerate(subs):
            last = k == len(subs) - 1
            base = relative if k == 0 else sapien.Pose()
            helper = f"{name}_dummy_{k}" if maniskill_names else f"{name}:{sub.name}"
            link = LinkPlan(
                name if last else helper,
                parent_index,
                b if last else None,
                sub,
                pose_in_parent=base * sub.frame_in_child * sub.ref_offset,
            )
            if last:
                _body_inertial(model, b, link, notes, centre[b])
            art.links.append(link)
            parent_index = len(art.links) - 1
        body_link[b] = (a, len(art.links) - 1)
    if len(articulations) == 1 and mj.model_name(model):  # one tree is the model: it takes the model's name
        articulations[0].name = mj.model_name(model)
    tree = TreePlan(articulations, body_link, notes)
    if maniskill_names:
        _dummy_roots(model, tree, centre)
    return tree


def _is_wrapper(model: mujoco.MjModel, b: int) -> bool:
    """ManiSkill's loader skips a root body with no geom, no joint (a free joint aside) and exactly one child body."""
    joints = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
    children = np.count_nonzero(model.body_parentid[1:] == b)
    return model.body_geomnum[b] == 0 and all(model.jnt_type[j] == FREE for j in joints) and children == 1


def _dummy_roots(model: mujoco.MjModel, tree: TreePlan, centre: np.ndarray) -> None:
    """Each world-child tree's root named `dummy_root_<i>` as ManiSkill's loader names it: an anchor link or a
    wrapper body's link takes the name; otherwise a helper link becomes the root and carries the body by a fixed
    joint. A floating helper keeps its centre of mass at the body's, so PhysX's root velocities stay the body's."""
    world_children = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    for a, art in enumerate(tree.articulations):
        if art.root_body not in world_children:
            continue  # a free body deeper in the tree: ManiSkill's loader has no articulation for it
        name = f"dummy_root_{world_children.index(art.root_body)}"
        root = art.links[0]
        if root.body is None or _is_wrapper(model, root.body):
            root.name = name
            continue
        helper = LinkPlan(name, None, None, JointPlan(root.joint.type), cmass=pose(centre[root.body]))
        root.joint = JointPlan("fixed")
        for link in art.links:
            link.parent = 0 if link.parent is None else link.parent + 1
        art.links.insert(0, helper)
        for b, (tree_index, link) in tree.body_link.items():
            if tree_index == a:
                tree.body_link[b] = (a, link + 1)
