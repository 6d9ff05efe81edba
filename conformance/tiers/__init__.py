"""The tiers: plain functions `tier(result, model, seed, tolerances) -> TierReport`, no Rerun, no I/O."""

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
