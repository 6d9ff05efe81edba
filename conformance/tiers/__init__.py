"""The tiers: plain functions `tier(result, model, seed, tolerances) -> TierReport`, no Rerun, no I/O.

`result` is a `loader.LoadResult`, `model` the MuJoCo reference (never modified: MuJoCo runs use copies),
`seed` drives configurations and commands, `tolerances` a `conformance.tolerances.Tolerances`.
Side effects on the SAPIEN scene: every tier may set its state (each ends at the start state); `dynamics`
and `actuated` turn every collision shape off (PhysX crashes when shapes are turned back on after stepping without
them), so run `contact` and `actuated_contact` first (the order of `TIERS`) or give them a fresh load; `actuated`
and `actuated_contact` enable SAPIEN's actuators and disable them again after.
"""

from .actuated import actuated, actuated_contact
from .collision import collision
from .contact import contact
from .dynamics import dynamics
from .inertia import inertia
from .kinematics import kinematics
from .maniskill import maniskill, maniskill_tensor
from .structure import structure

TIERS = {
    "structure": structure,
    "kinematics": kinematics,
    "inertia": inertia,
    "collision": collision,
    "contact": contact,  # before dynamics, which turns contacts off in the scene
    "actuated_contact": actuated_contact,  # before actuated and dynamics, which turn contacts off
    "actuated": actuated,
    "dynamics": dynamics,
    "maniskill": maniskill,  # opt-in (not a default tier): its own ManiSkill scene, no side effect on `result`
    "maniskill_tensor": maniskill_tensor,  # opt-in, as `maniskill`
}

__all__ = [
    "TIERS",
    "actuated",
    "actuated_contact",
    "collision",
    "contact",
    "dynamics",
    "inertia",
    "kinematics",
    "maniskill",
    "maniskill_tensor",
    "structure",
]
