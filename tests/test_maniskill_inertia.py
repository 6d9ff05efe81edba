"""The joint-space inertia M and bias c on tensors (loader/maniskill/inertia.py) from the built articulation's tree
(loader/plan/rigid_tree.py). MuJoCo is the oracle: at random states, M and c are MuJoCo's on fixed-base robots, and
on floating ones the joint accelerations they give are MuJoCo's (the root's coordinates differ by convention). Needs
torch (the `maniskill` extra)."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, menagerie_root, suite_path

torch = pytest.importorskip("torch", reason="torch is not installed (the `maniskill` extra)")

from loader import MJCFLoader
from loader.maniskill.free_root import free_velocity
from loader.maniskill.inertia import Inertia, frames, mass_matrix_and_bias
from loader.model.frames import quat_to_mat as rotation
from loader.plan.joint_actuation import robot_indices
from loader.plan.rigid_tree import rigid_tree

# relative, the largest |law - MuJoCo| of M, c and the accelerations over 8 random states (mujoco 3.17.0, sapien 3.0.3,
# torch 2.13.0): measured 6.6e-6 (the panda's c; PhysX's float32 masses, inertias and frames); the link origins
# 1.2e-6 m from SAPIEN's own. The mistakes below miss by 0.29 or more.
INERTIA_TOLERANCE = 1e-4


def _robot(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(str(path))
    return result, result.articulations[0]


def _paths():
    paths = [FIXTURES / "folding_servo_arm.xml", suite_path("cheetah"), suite_path("humanoid")]
    root = menagerie_root()
    if root is not None:
        paths += [root / "franka_emika_panda/panda.xml", root / "unitree_go1/go1.xml"]
    return [pytest.param(p, id=p.stem) for p in paths]


def _mistaken(inertia: Inertia, mistake: str | None) -> None:
    """A small mistake: the joints' armature left out, the links' gravity left out, or each link's centre of mass
    put at its frame's origin."""
    if mistake == "no_armature":
        inertia.armature_matrix.zero_()
    elif mistake == "weightless":
        inertia.weight.zero_()
    elif mistake == "centre_at_origin":
        inertia.centre.zero_()


def _state(model, data, result, articulation, rng):
    """A random state set on both sides: SAPIEN's joint positions (within limits) and velocities, MuJoCo's from them,
    and a floating root's random velocity (MuJoCo's free joint convention). Returns the law's inputs, PhysX's root
    velocity (its centre's, its spin, world frame) and MuJoCo's DoFs in the law's order (a free joint's first)."""
    dofs, _ = robot_indices(result.mapping)
    joints = sorted(dofs, key=dofs.get)
    low, high = np.asarray(articulation.get_qlimits()).T
    q = np.clip(rng.uniform(-0.5, 0.5, articulation.dof), np.maximum(low, -9), np.minimum(high, 9))
    articulation.set_qpos(q.astype(np.float32))
    q = np.asarray(articulation.get_qpos(), np.float64)
    v = rng.uniform(-2, 2, articulation.dof)
    mujoco.mj_resetData(model, data)
    data.qpos[model.jnt_qposadr[joints]], data.qvel[model.jnt_dofadr[joints]] = q, v
    root = articulation.get_root_pose()
    pose = torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None]
    order, velocity, physx = list(model.jnt_dofadr[joints]), None, None
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if free:  # MuJoCo: the body origin's velocity in the world frame, the spin in the body frame
        address, dof = model.jnt_qposadr[free[0]], model.jnt_dofadr[free[0]]
        data.qpos[address : address + 3], data.qpos[address + 3 : address + 7] = root.p, root.q
        data.qvel[dof : dof + 6] = rng.uniform(-1, 1, 6)
        order = list(range(dof, dof + 6)) + order
        velocity = torch.tensor(data.qvel[dof : dof + 6].copy())[None]
        turn = rotation(root.q)
        spin = turn @ data.qvel[dof + 3 : dof + 6]
        offset = turn @ np.asarray(articulation.links[0].cmass_local_pose.p, np.float64)
        physx = torch.tensor(np.r_[data.qvel[dof : dof + 3] + np.cross(spin, offset), spin])[None]
    mujoco.mj_forward(model, data)
    return torch.tensor(q)[None], torch.tensor(v)[None], pose, velocity, physx, order


def _worst(path, mistake: str | None = None) -> float:
    """The largest relative error of M, c and the accelerations they give under the bias alone, over 8 random
    states; on a floating robot also of its free joint's velocity as the law converts PhysX's."""
    result, articulation = _robot(path)
    model, data = result.model, mujoco.MjData(result.model)
    tree = rigid_tree(articulation)
    inertia = Inertia(tree, model.opt.gravity, [], "cpu")
    _mistaken(inertia, mistake)
    rng, worst = np.random.default_rng(0), 0.0
    dense = np.zeros((model.nv, model.nv))
    for _ in range(8):
        q, v, pose, velocity, physx, order = _state(model, data, result, articulation, rng)
        matrix, bias = (x[0].numpy() for x in mass_matrix_and_bias(inertia, q, v, pose, velocity))
        mujoco.mj_fullM(model, data, dense)
        accelerations = np.linalg.solve(matrix, -bias)
        expected = np.linalg.solve(dense, -data.qfrc_bias)[order]
        ordered = dense[np.ix_(order, order)]
        errors = [
            np.abs(accelerations - expected).max() / np.abs(expected).max(),
            np.abs(matrix - ordered).max() / np.abs(ordered).max(),
            np.abs(bias - data.qfrc_bias[order]).max() / np.abs(data.qfrc_bias[order]).max(),
        ]
        if physx is not None:
            converted = free_velocity(inertia, pose, physx)
            errors.append(float((converted - velocity).abs().max()))
        worst = max(worst, *errors)
    return worst


@pytest.mark.parametrize("path", _paths())
def test_the_inertia_and_bias_are_mujocos(path):
    """M and c are MuJoCo's on fixed-base robots (the stiff arm, the cheetah on its slides, the panda) and on floating
    ones (the humanoid, go1; random root velocities), whose free joint takes MuJoCo's coordinates; so are the
    accelerations under the bias alone."""
    assert _worst(path) < INERTIA_TOLERANCE


@pytest.mark.parametrize("mistake", ["no_armature", "weightless", "centre_at_origin"])
def test_each_mistake_in_the_inertia_is_caught(mistake):
    """The cheetah (armature, gravity, centres of mass off the link frames) catches each mistake."""
    assert _worst(suite_path("cheetah"), mistake) > INERTIA_TOLERANCE


def test_the_link_frames_are_sapiens():
    """The frames the law derives from the joint positions are SAPIEN's own link poses (the humanoid, at a random
    state): every joint turns about its frame's x axis and the tree is walked parents first."""
    result, _ = _robot(suite_path("humanoid"))
    articulation = result.articulations[0]  # the result keeps its scene alive
    tree = rigid_tree(articulation)
    inertia = Inertia(tree, [0, 0, -9.81], [], "cpu")
    rng = np.random.default_rng(1)
    articulation.set_qpos(rng.uniform(-0.5, 0.5, articulation.dof).astype(np.float32))
    q = torch.tensor(np.asarray(articulation.get_qpos(), np.float64))[None]
    root = articulation.get_root_pose()
    turn, origin, _, _ = frames(inertia, q, torch.tensor(np.r_[root.p, root.q], dtype=torch.float64)[None])
    for i, link in enumerate(articulation.links):
        assert np.abs(origin[0, i].numpy() - link.entity_pose.p).max() < 1e-5
        assert np.abs(turn[0, i].numpy() - rotation(link.entity_pose.q)).max() < 1e-5
