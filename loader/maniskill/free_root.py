"""A floating root's velocity from PhysX's convention to MuJoCo's free joint's, on tensors.

PhysX gives a root link's velocity as its centre of mass's and its spin, both in the world frame; MuJoCo's free joint
has its frame origin's velocity in the world frame and its spin in its own frame, the coordinates in which the law's
M and c are MuJoCo's (tests/test_maniskill_inertia.py).
"""

from __future__ import annotations

import torch

from .inertia import Inertia, root_frame


def free_velocity(law: Inertia, root_pose: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
    """MuJoCo's free joint velocity (env, 6: the root frame origin's, in the world frame; the spin, in the root's
    frame) from PhysX's root link velocity (env, 6: its centre of mass's, and the spin, both in the world frame)."""
    rotation = root_frame(law, root_pose)[:, :3, :3]
    spin = velocity[:, 3:]
    offset = (rotation @ law.centre[0][:, None])[..., 0]  # the centre of mass from the origin, in the world frame
    origin = velocity[:, :3] - torch.linalg.cross(spin, offset)
    return torch.cat((origin, (rotation.transpose(-1, -2) @ spin[..., None])[..., 0]), -1)
