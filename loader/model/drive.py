"""Joint drives: MuJoCo's passive spring-damper and its PD-form actuators as one PhysX drive per DoF.

MuJoCo's damping (and kv under implicitfast) is implicit and its springs and kp explicit; a PhysX drive is
implicit in both, and with damping D' = D - K dt its force over a step is MuJoCo's. The state-independent part
becomes the position target, the velocity target, or a generalized force. Derivation:
docs/mapping.md#joint-drives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class DofDrive:
    """Joint-space force law on one DoF: constant - stiffness * q - damping * qdot (MuJoCo's terms)."""

    stiffness: float = 0.0
    damping: float = 0.0
    constant: float = 0.0
    force_limit: float = np.inf

    def physx_damping(self, timestep: float) -> float:
        """The PhysX drive damping that reproduces MuJoCo's semi-implicit step (clamped at 0)."""
        return max(self.damping - self.stiffness * timestep, 0.0)


def apply(
    joint,
    drive: DofDrive,
    constant: float,
    timestep: float,
    via_damping: float = 0.0,
    written: dict | None = None,
    key=None,
    offset: float = 0.0,
) -> float:
    """Configure `joint`'s drive for the force law with state-independent part `constant`; returns the
    generalized force left to apply with `set_qf` (non-zero only for a DoF with neither stiffness nor damping).
    `via_damping` is a further constant force carried by the velocity target when the drive has damping (a
    large explicit force cancelled by the implicit damping loses digits in PhysX's float32 `qf`). `offset` is the
    velocity the drive's measure is short of this step (a slide on a turning link, `runtime/slides.py`): it joins the
    velocity target, and offset x dt the position target, so the drive's force is MuJoCo's. `written`
    remembers, by `key`, what was last written to the joint, so that unchanged settings are not written again
    (the caller owns the drive: a change made to it elsewhere is not seen)."""
    damping = drive.physx_damping(timestep)
    if drive.stiffness > 0:
        target, constant = constant / drive.stiffness + offset * timestep, 0.0
    else:
        target = 0.0
    velocity_target, left = 0.0, constant + via_damping
    if damping > 0:
        velocity_target, left = left / damping + offset, 0.0
    properties = (drive.stiffness, damping, drive.force_limit)
    last = written.get(key) if written is not None else None
    if last is None or last[0] != properties:
        joint.set_drive_properties(drive.stiffness, damping, drive.force_limit, "force")
    if last is None or last[1] != target:
        joint.set_drive_target(target)
    if last is None or last[2] != velocity_target:
        joint.set_drive_velocity_target(velocity_target)
    if written is not None:
        written[key] = (properties, target, velocity_target)
    return left
