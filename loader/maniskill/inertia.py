"""An articulation's joint-space inertia M and bias c (Coriolis, centrifugal and gravity) at a state, over (env, DoF)
tensors, from its rigid-body tree (`loader/plan/rigid_tree.py`): the numbers PhysX's articulation steps with, so that
a joint force `qf = M (v1 - v0) / dt + c` takes its joints from v0 to v1 in one step, with no MuJoCo call and no
per-env, per-link or per-DoF loop.

The link frames follow from the root's pose and the joint positions, each link's frame its parent's times its joint's
transform; the products down the tree are taken by pointer doubling, log2 of its depth rounds of one product each.
Each DoF's joint has its axis a_j through the point p_j. DoF j moves the centre of mass c_i of a link below it by
a_j x (c_i - p_j) (a slide: a_j) and turns it by a_j (a slide: not at all): the Jacobians Jv_i, Jw_i. A floating root
adds six coordinates in front, as MuJoCo's free joint has them: its frame's origin's velocity in the world frame, and
its angular velocity in its own frame (three axes b_k turning with it, through its origin). Then, Kane's form of the
link's Newton-Euler equations summed over the tree,

    M = sum_i m_i Jv_i^T Jv_i + Jw_i^T I_i Jw_i + diag(armature),
    c = sum_i Jv_i^T m_i (dJv_i v - g_i) + Jw_i^T (I_i dJw_i v + w_i x I_i w_i),

dJ v the Jacobians' rates along the motion (a_j turns with its link at w_j; p_j moves with it), g_i gravity where
the link's is on (tests/test_maniskill_inertia.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch

from ..plan.rigid_tree import PRISMATIC, REVOLUTE, RigidTree


def _quaternion_basis() -> np.ndarray:
    """(16, 9): a unit quaternion's rotation matrix (row-major) from its products q_a q_b (a, b in w, x, y, z)."""
    basis = np.zeros((4, 4, 3, 3))
    w, x, y, z = range(4)

    def add(i, j, terms):
        for sign, a, b in terms:
            basis[a, b, i, j] += sign

    add(0, 0, [(1, w, w), (1, x, x), (-1, y, y), (-1, z, z)])
    add(1, 1, [(1, w, w), (-1, x, x), (1, y, y), (-1, z, z)])
    add(2, 2, [(1, w, w), (-1, x, x), (-1, y, y), (1, z, z)])
    add(0, 1, [(2, x, y), (-2, w, z)])
    add(1, 0, [(2, x, y), (2, w, z)])
    add(0, 2, [(2, x, z), (2, w, y)])
    add(2, 0, [(2, x, z), (-2, w, y)])
    add(1, 2, [(2, y, z), (-2, w, x)])
    add(2, 1, [(2, y, z), (2, w, x)])
    return basis.reshape(16, 9)


def _motion_basis() -> tuple[np.ndarray, np.ndarray]:
    """A joint's motion (4 x 4, flat) as (cos, sin, shift) @ basis + fixed: turning about x by an angle with that
    cosine and sine, then sliding along x by the shift."""
    fixed, basis = np.zeros((4, 4)), np.zeros((3, 4, 4))
    fixed[0, 0] = fixed[3, 3] = 1.0
    basis[0, 1, 1] = basis[0, 2, 2] = 1.0  # cos
    basis[1, 2, 1], basis[1, 1, 2] = 1.0, -1.0  # sin
    basis[2, 0, 3] = 1.0  # shift
    return basis.reshape(3, 16), fixed.reshape(16)


def _homogeneous(position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(n, 4, 4) transforms from (n, 3) positions and (n, 3, 3) rotations."""
    out = np.tile(np.eye(4), (position.shape[0], 1, 1))
    out[:, :3, :3], out[:, :3, 3] = rotation, position
    return out


class Inertia:
    """The tree's arrays as tensors on one device and dtype, and the link gravity (`gravity`, 3; `weightless`: the
    links PhysX's gravity does not pull)."""

    def __init__(self, tree: RigidTree, gravity, weightless, device, dtype=torch.float64):
        def tensor(array, kind=dtype):
            return torch.as_tensor(np.asarray(array), dtype=kind, device=device)

        self.floating = tree.floating
        nlink = tree.mass.size
        self.revolute = tensor((tree.kind == REVOLUTE) & (tree.dof >= 0), dtype)
        self.prismatic = tensor((tree.kind == PRISMATIC) & (tree.dof >= 0), dtype)
        self.dof = tensor(np.maximum(tree.dof, 0), torch.long)
        self.joint_in_parent = tensor(_homogeneous(tree.joint_position, tree.joint_rotation))
        self.link_in_joint = tensor(_homogeneous(tree.link_position, tree.link_rotation))
        # pointer doubling: each round's ancestor of every link, the tree's links then one identity past them
        parent = np.where(tree.parent >= 0, tree.parent, nlink)
        ancestor, rounds = np.append(parent, nlink), []
        for _ in range(max(int(np.ceil(np.log2(tree.depth + 1))), 1)):
            rounds.append(tensor(ancestor, torch.long))
            ancestor = ancestor[ancestor]
        self.rounds = rounds
        self.parent = tensor(parent, torch.long)
        self.mass, self.centre, self.inertia = tensor(tree.mass), tensor(tree.centre), tensor(tree.inertia)
        self.link_of_dof = tensor(tree.link_of_dof, torch.long)
        # (nlink, ndof, 1): 1 where the DoF moves the link, by turning it (a hinge) or by sliding it
        turning = tree.kind[tree.link_of_dof] == REVOLUTE
        self.moved_turning = tensor((tree.ancestors & turning[None, :])[..., None], dtype)
        self.moved_sliding = tensor((tree.ancestors & ~turning[None, :])[..., None], dtype)
        root = 6 if tree.floating else 0
        self.armature_matrix = tensor(np.diag(np.concatenate((np.zeros(root), tree.armature))))
        pulled = np.ones(nlink)
        pulled[list(weightless)] = 0.0
        self.weight = tensor(pulled[:, None] * np.asarray(gravity, np.float64)[None, :])  # (nlink, 3): g_i
        self.eye = torch.eye(3, dtype=dtype, device=device)
        self.identity = torch.eye(4, dtype=dtype, device=device)
        self.bottom = tensor([[0.0, 0.0, 0.0, 1.0]])
        self.quaternion_basis = tensor(_quaternion_basis())
        basis, fixed = _motion_basis()
        self.motion_basis, self.motion_fixed = tensor(basis), tensor(fixed)


def root_frame(law: Inertia, root_pose: torch.Tensor) -> torch.Tensor:
    """(env, 4, 4): the root's pose (env, 7: position, unit quaternion w, x, y, z) as a transform."""
    quaternion = root_pose[:, 3:]
    products = (quaternion[:, :, None] * quaternion[:, None, :]).reshape(-1, 16)
    rotation = (products @ law.quaternion_basis).reshape(-1, 3, 3)
    top = torch.cat((rotation, root_pose[:, :3, None]), -1)
    return torch.cat((top, law.bottom.expand(top.shape[0], 1, 4)), 1)


def frames(law: Inertia, q: torch.Tensor, root_pose: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Each link's frame (rotation (env, nlink, 3, 3), origin (env, nlink, 3)) and each DoF's joint frame after its
    motion (rotation, origin) at joint positions q (env, ndof) and the root's pose (env, 7: position, quaternion)."""
    env = q.shape[0]
    at = q[:, law.dof]  # (env, nlink): each link's joint position (zero where it has none)
    angle = at * law.revolute
    motion = torch.stack((torch.cos(angle), torch.sin(angle), at * law.prismatic), -1) @ law.motion_basis
    motion = (motion + law.motion_fixed).reshape(env, -1, 4, 4)
    joint = law.joint_in_parent @ motion  # (env, nlink, 4, 4): each joint's frame in its parent link
    local = joint @ law.link_in_joint
    world = torch.cat((root_frame(law, root_pose)[:, None], local[:, 1:], law.identity.expand(env, 1, 4, 4)), 1)
    for ancestor in law.rounds:
        world = world[:, ancestor] @ world
    links = world[:, :-1]
    dofs = law.link_of_dof
    joints = world[:, law.parent[dofs]] @ joint[:, dofs]
    return links[..., :3, :3], links[..., :3, 3], joints[..., :3, :3], joints[..., :3, 3]


class Motion(NamedTuple):
    """The tree's kinematics at a state (`motion`): link frames and centres, joint frames, the Jacobians of each
    centre's velocity and each link's spin (env, nlink, n, 3), the coordinates' speeds (env, n), each centre's
    velocity and each link's spin, and per DoF its axis's rate and its anchor point's velocity."""

    rotation: torch.Tensor
    origin: torch.Tensor
    joint_origin: torch.Tensor
    centre: torch.Tensor
    axis: torch.Tensor  # (env, nlink, ndof, 3): a_j, repeated per link
    linear: torch.Tensor
    angular: torch.Tensor
    speed: torch.Tensor
    velocity: torch.Tensor
    spin: torch.Tensor
    axis_rate: torch.Tensor  # (env, ndof, 3): a_j turning with its link
    anchor: torch.Tensor  # (env, ndof, 3): dp_j/dt


def motion(
    law: Inertia, q: torch.Tensor, v: torch.Tensor, root_pose: torch.Tensor, root_velocity: torch.Tensor | None = None
) -> Motion:
    """The tree's kinematics at joint positions q and velocities v (env, ndof), the root's pose (env, 7) and, with a
    floating root, its velocity (env, 6: MuJoCo's free joint's, `free_root.free_velocity`)."""
    env, nlink = q.shape[0], law.mass.shape[0]
    rotation, origin, joint_rotation, joint_origin = frames(law, q, root_pose)
    centre = origin + (rotation @ law.centre[..., None])[..., 0]  # (env, nlink, 3)
    axis = joint_rotation[..., 0][:, None].expand(env, nlink, -1, 3)  # a_j
    lever = centre[:, :, None, :] - joint_origin[:, None, :, :]  # (env, nlink, ndof, 3): c_i - p_j
    linear = torch.linalg.cross(axis, lever) * law.moved_turning + axis * law.moved_sliding
    angular = axis * law.moved_turning
    speed = v
    if law.floating:
        root_linear, root_angular = _root_columns(law, rotation, origin, centre)
        linear, angular = torch.cat((root_linear, linear), 2), torch.cat((root_angular, angular), 2)
        speed = torch.cat((root_velocity, v), 1)
    weights = speed[:, None, :, None]
    velocity, spin = (linear * weights).sum(2), (angular * weights).sum(2)  # each centre's, each link's spin
    # the Jacobians' rates along the motion: a_j turns at w_j, its link's; p_j moves with that link
    dofs = law.link_of_dof
    axis_rate = torch.linalg.cross(spin[:, dofs], axis[:, 0])  # (env, ndof, 3)
    anchor = velocity[:, dofs] + torch.linalg.cross(spin[:, dofs], joint_origin - centre[:, dofs])
    return Motion(
        rotation, origin, joint_origin, centre, axis, linear, angular, speed, velocity, spin, axis_rate, anchor
    )


def _root_columns(law: Inertia, rotation: torch.Tensor, origin: torch.Tensor, point: torch.Tensor):
    """A floating root's six columns of the Jacobians of points (env, k, 3) on its tree, of their velocities and of
    their links' spins, (env, k, 6, 3) each, as MuJoCo's free joint has its coordinates: the origin's velocity in
    the world frame (the identity; no spin) and the spin in the root's frame (its three axes b_k turning with it,
    through its origin: b_k x (p - o), and b_k)."""
    env, count = point.shape[:2]
    eye = law.eye.expand(env, count, 3, 3)
    axes = rotation[:, :1].transpose(-1, -2).expand(env, count, 3, 3)  # row k: the root's axis k in the world
    arm = (point - origin[:, :1])[:, :, None, :].expand(env, count, 3, 3)  # p - o
    return torch.cat((eye, torch.linalg.cross(axes, arm)), 2), torch.cat((torch.zeros_like(eye), axes), 2)


def _root_rate(moved: Motion, velocity: torch.Tensor) -> torch.Tensor:
    """What a floating root's columns add to dJ/dt v of points moving at `velocity` (env, k, 3): its axes turn with
    it, sum_k w_k d/dt (b_k x (p - o)) = w x (V_p - v_o), w its spin (in the world frame) and v_o its origin's
    velocity; its spin columns add nothing (sum_k w_k w x b_k = 0)."""
    return torch.linalg.cross(moved.spin[:, :1], velocity - moved.speed[:, None, :3])


def _rate(law: Inertia, moved: Motion, v: torch.Tensor, lever: torch.Tensor, velocity: torch.Tensor, links):
    """dJ/dt v of points on links `links` (env, k, 3): for each DoF j moving them, the rate of a_j x (p - p_j)
    (a slide: of a_j) along the motion, p moving at `velocity` (env, k, 3), `lever` p - p_j (env, k, ndof, 3)."""
    relative = velocity[:, :, None, :] - moved.anchor[:, None, :, :]  # V_p - dp_j/dt
    rate = moved.axis_rate[:, None].expand_as(lever)
    turned = torch.linalg.cross(rate, lever) + torch.linalg.cross(moved.axis[:, :1].expand_as(lever), relative)
    weights = v[:, None, :, None]
    return (turned * (law.moved_turning[links] * weights) + rate * (law.moved_sliding[links] * weights)).sum(2)


def points_and_jacobians(
    law: Inertia, moved: Motion, v: torch.Tensor, links: torch.Tensor, local: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Points fixed on links `links` (k,) at `local` (k, 3) in each link's frame: their world positions (env, k, 3),
    their linear Jacobians over the coordinates (env, k, n, 3; row j what coordinate j adds to the point's velocity;
    a floating root's six first) and the acceleration the velocities alone give them, dJ/dt v (env, k, 3), from the
    tree's `motion` at joint velocities v
    (tests/test_maniskill_joint_actuation.py::test_the_laws_connects_are_mujocos, and the floating loops' test)."""
    point = moved.origin[:, links] + (moved.rotation[:, links] @ local[..., None])[..., 0]
    lever, jacobian = _levers_and_jacobians(law, moved, links, point)
    velocity = (jacobian * moved.speed[:, None, :, None]).sum(2)
    rate = _rate(law, moved, v, lever, velocity, links)
    return point, jacobian, rate + _root_rate(moved, velocity) if law.floating else rate


def point_jacobians(law: Inertia, moved: Motion, links: torch.Tensor, point: torch.Tensor) -> torch.Tensor:
    """The linear Jacobians (env, k, n, 3) of points (env, k, 3, in the world frame) moving with links `links` (k,),
    from the tree's `motion`."""
    return _levers_and_jacobians(law, moved, links, point)[1]


def _levers_and_jacobians(law: Inertia, moved: Motion, links: torch.Tensor, point: torch.Tensor):
    """p - p_j (env, k, ndof, 3) and the points' linear Jacobians over the coordinates (env, k, n, 3)."""
    lever = point[:, :, None, :] - moved.joint_origin[:, None]  # (env, k, ndof, 3): p - p_j
    axis = moved.axis[:, :1].expand_as(lever)
    jacobian = torch.linalg.cross(axis, lever) * law.moved_turning[links] + axis * law.moved_sliding[links]
    if law.floating:
        jacobian = torch.cat((_root_columns(law, moved.rotation, moved.origin, point)[0], jacobian), 2)
    return lever, jacobian


def turning(law: Inertia, moved: Motion, v: torch.Tensor, links: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Links `links` (k,): their rotations (env, k, 3, 3), the Jacobians of their spins over the coordinates (env, k,
    n, 3; a floating root's six first), their spins (env, k, 3) and what the velocities alone add to them per unit
    time, dJw/dt v (env, k, 3; nothing from the root's columns), from the tree's `motion` at joint velocities v
    (tests/test_maniskill_joint_actuation.py::test_the_laws_welds_are_mujocos, and the floating loops' test)."""
    jacobian = moved.axis[:, :1].expand(-1, links.shape[0], -1, -1) * law.moved_turning[links]
    if law.floating:
        jacobian = torch.cat((_root_columns(law, moved.rotation, moved.origin, moved.origin[:, links])[1], jacobian), 2)
    rate = (moved.axis_rate[:, None] * (law.moved_turning[links] * v[:, None, :, None])).sum(2)
    return moved.rotation[:, links], jacobian, moved.spin[:, links], rate


def mass_matrix_and_bias(
    law: Inertia,
    q: torch.Tensor,
    v: torch.Tensor,
    root_pose: torch.Tensor,
    root_velocity: torch.Tensor | None = None,
    moved: Motion | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """M (env, n, n) and c (env, n) at joint positions q and velocities v (env, ndof) and the root's pose (env, 7);
    with a floating root, n = 6 + ndof, its coordinates first, as MuJoCo's free joint has them: `root_velocity`
    (env, 6), the root frame's origin's velocity in the world frame and its angular velocity in its own frame
    (`free_root.free_velocity` converts PhysX's). The Jacobians are laid out (env, nlink, n, 3): row k is what
    coordinate k adds to the link's velocity. `moved`: the tree's `motion` at that state, where the caller has it."""
    env = q.shape[0]
    moved = motion(law, q, v, root_pose, root_velocity) if moved is None else moved
    rotation, centre, linear, angular = moved.rotation, moved.centre, moved.linear, moved.angular
    velocity, spin, speed = moved.velocity, moved.spin, moved.speed
    inertia = rotation @ law.inertia @ rotation.transpose(-1, -2)  # about it, in the world frame
    lever = centre[:, :, None, :] - moved.joint_origin[:, None, :, :]  # c_i - p_j
    acceleration = _rate(law, moved, v, lever, velocity, slice(None))
    weights = v[:, None, :, None]
    spin_rate = (moved.axis_rate[:, None].expand_as(lever) * (law.moved_turning * weights)).sum(2)
    if law.floating:
        acceleration = acceleration + _root_rate(moved, velocity)
    force = law.mass[:, None] * (acceleration - law.weight)  # (env, nlink, 3)
    torque = inertia @ torch.stack((spin_rate, spin), -1)  # I dw and I w, as two columns
    torque = torque[..., 0] + torch.linalg.cross(spin, torque[..., 1])
    bias = ((linear * force[:, :, None]).sum(-1) + (angular * torque[:, :, None]).sum(-1)).sum(1)
    weighted = linear * law.mass[:, None, None]
    turned = angular @ inertia  # (env, nlink, n, 3): each column's I J_w, as rows (I is symmetric)
    rows = torch.cat((weighted, turned), -1).transpose(1, 2).reshape(env, speed.shape[1], -1)
    columns = torch.cat((linear, angular), -1).transpose(1, 2).reshape(env, speed.shape[1], -1)
    matrix = rows @ columns.transpose(1, 2) + law.armature_matrix
    return matrix, bias
