"""The rigid-body tree read from a built articulation (loader/plan/rigid_tree.py): which slides keep no drive in
`mujoco_ctrl_tensor`, and how the tree is walked. The M and c it gives are tested against MuJoCo in
tests/test_maniskill_inertia.py (the `maniskill` extra)."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
from support.corpus import suite_path
from test_joint_actuation import SIBLINGS

from loader import MJCFLoader
from loader.plan.rigid_tree import PRISMATIC, REVOLUTE, rigid_tree, turning_slides


def _tree(source):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(source)
    return result, rigid_tree(result.articulations[0])


def _names(result, mask) -> set[str]:
    return {joint.name for joint, marked in zip(result.articulations[0].active_joints, mask) if marked}


def test_slides_below_a_hinge_turn_and_slides_above_every_hinge_do_not():
    """The gripper's fingers slide on a turning hand: both are turning slides. The cheetah's root slides (rootx,
    rootz) come before every hinge of the chain and never turn; its hinges are no slides."""
    result, tree = _tree(mujoco.MjSpec.from_string(SIBLINGS.format(integrator="implicitfast")))
    assert _names(result, turning_slides(tree)) == {"l", "r"}
    result, tree = _tree(str(suite_path("cheetah")))
    assert _names(result, turning_slides(tree)) == set()
    kinds = tree.kind[tree.link_of_dof]
    assert _names(result, kinds == PRISMATIC) == {"rootx", "rootz"}
    assert np.count_nonzero(kinds == REVOLUTE) == tree.armature.size - 2


def test_the_tree_lists_parents_first_and_each_dof_once():
    """Every link's parent comes before it, each DoF has one link, and a DoF moves its own link and every link below."""
    _, tree = _tree(str(suite_path("humanoid")))
    assert (tree.parent[1:] < np.arange(1, tree.parent.size)).all() and tree.parent[0] == -1
    assert sorted(tree.dof[tree.dof >= 0]) == list(range(tree.armature.size))
    for dof, link in enumerate(tree.link_of_dof):
        below = {i for i in range(tree.parent.size) if _above(tree.parent, i, link)}
        assert set(np.flatnonzero(tree.ancestors[:, dof])) == below | {link}
    assert tree.floating


def _above(parent, link, ancestor) -> bool:
    while parent[link] >= 0:
        link = parent[link]
        if link == ancestor:
            return True
    return False
