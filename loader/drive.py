"""Joint drives: MuJoCo's passive spring-damper and its PD-form actuators as one PhysX drive per DoF.

MuJoCo integrates joint damping implicitly (Euler and implicitfast), and under implicitfast also actuator kv,
while springs and actuator kp are explicit. A PhysX drive is implicit in both. With D' = D - K*dt the drive's
force over a step, K(p - q[t+1]) - D' v[t+1] = K(p - q[t]) - D v[t+1], is MuJoCo's. The state-independent part
of the force (K*springref, gear*(gain*ctrl + bias0)) becomes the drive's position target (K > 0), its velocity
target (K = 0, D' > 0), or a generalized force (neither).
A limit measured, not removable here: when a joint's velocity changes a lot in one step on a moving base,
PhysX's base reacts differently from MuJoCo's semi-implicit Euler, at O(dt^2) per step. A free box with one hinge
arm spinning at 3 rad/s (armature 0.01, dt 2 ms): with joint damping 2, the joint agrees with MuJoCo to 1.5e-7
after one step and the box's velocity differs by 1.3e-4 (6.0e-4 after 1 s; 5.3e-6 without the damping), whatever
the solver iterations. It is not the drive: the damping carried as armature dt D plus -D v (no drive row, exact
inside MuJoCo) gives the same 1.3e-4, and so does an applied joint torque of -6 N m without any damping (1.5e-4;
MuJoCo's own RK4 and Euler differ there by 1.2e-4). With the box at rest, PhysX's step is MuJoCo's
semi-implicit Euler with the velocity-product (Coriolis and centripetal) forces evaluated at the end-of-step
velocity: M (v' - v) = dt (f - c(q, v')) reproduces PhysX's box velocity to 2e-12..4e-9 where MuJoCo's c(q, v)
leaves 1.1e-5..1.7e-4 (torque 6 N m, joint speed 0..3 rad/s): the gap grows as (w + dw)^2 - w^2 in the joint's
speed w and its change dw over the step. Measured since: PhysX conserves the articulation's linear momentum over a
step exactly (float32: 1e-9 of go1's mass-weighted velocity with no gravity), MuJoCo's semi-implicit Euler does not:
its momentum moves by about dt (c(q, v') - c(q, v)) in the free joint's translational rows, and PhysX's root linear
velocity differs from MuJoCo's by that drift over the total mass (go1, legs at 2 rad/s: errors of 2e-5..1e-4 m/s,
each the drift to 3e-6), base at rest or moving. Angular momentum drifts in both, differently (go1: 1e-4 of
about 1e-4 N m s): the root's angular velocity is left at up to 1.7e-4 rad/s in one step. PhysX's source says why:
after the solve, a floating articulation's link velocities are rebuilt at the end-of-step poses from the root's and
the joints' new velocities, the linear momentum of the solver's velocities is restored exactly and the angular
momentum's magnitude rescaled (a rigid spin of every link); a fixed base skips this. Reproducing MuJoCo's drift
instead needs MuJoCo's end-of-step velocity before PhysX's step, so the loader leaves it: it is PhysX's integrator,
second order in dt per step, large where a joint's speed changes a lot in one step (damping on light links, stiff
servos). Without torques or damping the two agree to 1e-6.
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


def apply(joint, drive: DofDrive, constant: float, timestep: float, via_damping: float = 0.0,
          written: dict | None = None, key=None, offset: float = 0.0) -> float:
    """Configure `joint`'s drive for the force law with state-independent part `constant`; returns the
    generalized force left to apply with `set_qf` (non-zero only for a DoF with neither stiffness nor damping).
    `via_damping` is a further constant force carried by the velocity target when the drive has damping (a
    large explicit force cancelled by the implicit damping loses digits in PhysX's float32 `qf`). `offset` is the
    velocity the drive's measure is short of this step (a slide on a turning link, `slide.py`): it joins the
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
