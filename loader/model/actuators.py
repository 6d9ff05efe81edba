"""What the planning half hands the runtime about each actuator: its `ActuatorMap`, and the activation dynamics the
runtime steps (`runtime/activation.py`)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

DYN = mujoco.mjtDyn
MAPPED_DYNAMICS = {
    int(DYN.mjDYN_FILTER): "filter",
    int(DYN.mjDYN_FILTEREXACT): "filterexact",
    int(DYN.mjDYN_INTEGRATOR): "integrator",
    int(DYN.mjDYN_MUSCLE): "muscle",
}
SPATIAL: list = []  # the terms `map_actuator` gives an actuator on a spatial tendon (whose terms change with the pose)
MOMENT: list = []  # ... and one whose length and moment MuJoCo's transmission computes each step (`ActuatorMap.moment`)


@dataclass(frozen=True)
class ActuatorMap:
    """One MuJoCo actuator in SAPIEN. `stiffness` / `damping` are the joint-space gains it adds (gear² kp and
    gear² kv, MuJoCo's terms); the PhysX drive of a DoF sums them with the joint's passive terms and takes
    damping - stiffness x timestep as its damping (`drive.py`)."""

    name: str
    kind: str  # "motor", "position", "velocity", "general"
    joint: str | None
    tendon: str | None
    articulation: int | None
    dofs: tuple[int, ...]
    gear: float
    ctrlrange: tuple[float, float] | None
    forcerange: tuple[float, float] | None
    stiffness: float = 0.0
    damping: float = 0.0
    # MuJoCo's force law in actuator space: gain * ctrl + bias[0] + bias[1] * length + bias[2] * velocity
    gain: float = 0.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mapped: bool = True
    reason: str = ""
    dynamics: str = "none"  # "filter", "filterexact", "integrator": the gain multiplies the activation
    # a site, slider-crank, body or free-joint transmission: its length and moment (gear inside, so `gear` is 1) are
    # MuJoCo's at SAPIEN's state every step (`runtime/transmissions.py`)
    moment: bool = False
    # MuJoCo's muscle: gain and bias are its force-length-velocity curves of the length and rate, the gain times
    # the activation (`runtime/transmissions.py`); a muscle is always a moment actuator
    muscle: bool = False

    def unclamped(self, ctrl: float, length: float, velocity: float) -> float:
        """MuJoCo's actuator force law (before gear and before the forcerange clamp)."""
        return float(self.gain * ctrl + self.bias[0] + self.bias[1] * length + self.bias[2] * velocity)

    def force(self, ctrl: float, length: float, velocity: float) -> float:
        """The actuator force (before gear) this mapping applies, clamped to forcerange."""
        force = self.unclamped(ctrl, length, velocity)
        return min(max(force, self.forcerange[0]), self.forcerange[1]) if self.forcerange is not None else force
