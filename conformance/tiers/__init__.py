"""The tiers: plain functions `tier(result, model, seed, tolerances) -> TierReport`, no Rerun, no I/O.

`result` is a `loader.LoadResult`, `model` the MuJoCo reference (never modified: MuJoCo runs use copies),
`seed` drives configurations and commands, `tolerances` a `conformance.tolerances.Tolerances`.
Side effects on the SAPIEN scene: every tier may set its state (each ends at the start state); `dynamics`
turns every collision shape off, so run `contact` first (the order of `TIERS`) or give it a fresh load.
"""

from .collision import collision
from .contact import contact
from .dynamics import dynamics
from .inertia import inertia
from .kinematics import kinematics
from .structure import structure

TIERS = {
    "structure": structure,
    "kinematics": kinematics,
    "inertia": inertia,
    "collision": collision,
    "contact": contact,  # before dynamics, which turns contacts off in the scene
    "dynamics": dynamics,
}

__all__ = ["TIERS", "collision", "contact", "dynamics", "inertia", "kinematics", "structure"]
