"""A floating root on tensors: its velocity between PhysX's convention and MuJoCo's free joint's, and the root's end
of a physics step as MuJoCo's step leaves it.

PhysX gives a root link's velocity as its centre of mass's and its spin, both in the world frame; MuJoCo's free joint
has its frame origin's velocity in the world frame and its spin in its own frame, the coordinates in which the law's
M and c are MuJoCo's (tests/test_maniskill_inertia.py).

PhysX's articulation step conserves the tree's momentum where MuJoCo's semi-implicit Euler keeps qvel, so the two
roots part wherever the links turn against each other within a step, though the joints end alike
(docs/mapping.md#floating-bases). Where every force on the tree is the law's (no contact pushed it), MuJoCo's step
on the free joint's rows gives the root's end velocity from the joints' end velocities, whatever PhysX's solver did
to them (a joint limit's force has no share in those rows):

    M_rr (v1_r - v0_r) = dt (f_r - c_r) - M_rj (v1_j - v0_j),

M, c and f_r (the force of a loop's rows on the root, the only one the law puts there) at the step's start.
`RootRows` keeps that solve, taken at the start, and `settle` writes the root's end velocity and the pose MuJoCo's
position update gives into PhysX after the step
(tests/test_maniskill_joint_actuation.py::test_a_floating_robot_keeps_mujocos_root).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..runtime.momentum import MOVED  # float32's rounding of a joint position, relative to the largest
from .inertia import Inertia, root_frame


def free_velocity(law: Inertia, root_pose: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """MuJoCo's free joint velocity (env, 6: the root frame origin's, in the world frame; the spin, in the root's
    frame) from PhysX's root link velocity (env, 6: its centre of mass's, and the spin, both in the world frame)."""
    rotation = root_frame(law, root_pose)[:, :3, :3]
    spin = velocity[:, 3:]
    offset = (rotation @ law.centre[0][:, None])[..., 0]  # the centre of mass from the origin, in the world frame
    origin = velocity[:, :3] - torch.linalg.cross(spin, offset)
    return torch.cat((origin, (rotation.transpose(-1, -2) @ spin[..., None])[..., 0]), -1)


def physx_velocity(law: Inertia, root_pose: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """PhysX's root link velocity (env, 6) from MuJoCo's free joint velocity (env, 6): `free_velocity` undone."""
    rotation = root_frame(law, root_pose)[:, :3, :3]
    spin = (rotation @ velocity[:, 3:, None])[..., 0]
    offset = (rotation @ law.centre[0][:, None])[..., 0]
    return torch.cat((velocity[:, :3] + torch.linalg.cross(spin, offset), spin), -1)


def _turned(quaternion: torch.Tensor, turn: torch.Tensor) -> torch.Tensor:
    """The Hamilton product quaternion x turn (env, 4: w, x, y, z)."""
    aw, ax, ay, az = quaternion.unbind(-1)
    bw, bx, by, bz = turn.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        -1,
    )


def advanced(root_pose: torch.Tensor, velocity: torch.Tensor, timestep: float) -> torch.Tensor:
    """A free joint's pose (env, 7) after MuJoCo's position update (`mj_integratePos`): the origin moved by timestep
    times its velocity, the orientation turned by timestep times the spin in its own frame, then normalised."""
    spin = velocity[:, 3:]
    speed = torch.linalg.vector_norm(spin, dim=-1, keepdim=True)
    half = 0.5 * timestep * speed
    axis = spin / torch.clamp(speed, min=torch.finfo(spin.dtype).tiny)
    quaternion = _turned(root_pose[:, 3:], torch.cat((torch.cos(half), axis * torch.sin(half)), -1))
    quaternion = quaternion / torch.linalg.vector_norm(quaternion, dim=-1, keepdim=True)
    return torch.cat((root_pose[:, :3] + timestep * velocity[:, :3], quaternion), -1)


@dataclass
class RootRows:
    """The free joint's rows of MuJoCo's step, solved at its start: the root's end velocity (MuJoCo's convention) is
    `v0 + offset + gain @ v1_j` for the joints' end velocities v1_j; `q0`, `joint_v0` and `pose0` are the start's."""

    q0: torch.Tensor  # (env, ndof)
    joint_v0: torch.Tensor  # (env, ndof)
    pose0: torch.Tensor  # (env, 7)
    v0: torch.Tensor  # (env, 6), the free joint's
    offset: torch.Tensor  # (env, 6)
    gain: torch.Tensor  # (env, 6, ndof)
    timestep: float
    pending: torch.Tensor  # (env,) the envs whose step is still to settle (a reset takes its envs out)

    @staticmethod
    def solve(matrix, bias, q0, v0, pose0, root_velocity, timestep: float) -> RootRows:
        """From M (env, n, n) and c - f (env, n) at the start (the root's six coordinates first), the joints'
        positions and velocities `q0`, `v0` (env, ndof), the root's pose and free joint velocity."""
        rows = matrix[:, :6]
        right = torch.cat(((rows[:, :, 6:] @ v0[..., None]) - timestep * bias[:, :6, None], -rows[:, :, 6:]), -1)
        solved = torch.linalg.solve_ex(rows[:, :, :6], right)[0]
        pending = torch.ones(q0.shape[0], dtype=torch.bool, device=q0.device)
        return RootRows(q0, v0, pose0, root_velocity, solved[..., 0], solved[..., 1:], timestep, pending)

    def stepped(self, q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
        """(env,) whether the joints of a pending env moved from `q0` to `q` as PhysX's step moves them: by timestep
        times `v` (PGS), or by timestep times the velocities of TGS's substeps, which stray from `v` by no more than
        the step changed any joint's velocity; a state set from outside moves them further
        (tests/test_maniskill_joint_actuation.py::test_every_contact_free_tgs_step_of_a_damped_dog_is_settled)."""
        pad = torch.nn.functional.pad  # a zero column: a robot without joints moved as stepped
        dt = self.timestep
        strayed = pad(torch.abs(q - self.q0 - dt * v), (0, 1)).amax(-1)
        changed = pad(torch.abs(v - self.joint_v0), (0, 1)).amax(-1)
        rounding = MOVED * (1.0 + pad(torch.abs(q), (0, 1)).amax(-1))
        return self.pending & (strayed <= dt * changed + rounding)

    def end(self, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The root's pose (env, 7) and free joint velocity (env, 6) at the end of MuJoCo's step, the joints ending
        at `v` (env, ndof)."""
        velocity = self.v0 + self.offset + (self.gain @ v[..., None])[..., 0]
        return advanced(self.pose0, velocity, self.timestep), velocity
