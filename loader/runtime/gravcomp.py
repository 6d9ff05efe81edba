"""Body gravity compensation (`<body gravcomp>`): gravcomp = 1 turns PhysX's gravity off for the link; any other
value adds -gravcomp m g at the centre of mass once per step. Derivation: docs/mapping.md#gravity-compensation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import Notes
from ..model import mj
from ..model.mapping import Mapping
from .term import Compilation, LinkForces


@dataclass
class GravityCompensation(LinkForces):
    """Per-step forces on links whose bodies compensate gravity partly (or more than fully)."""

    forces: tuple[tuple[int, int, np.ndarray], ...]  # (articulation, link, world force)
    links: list | None = field(default=None, repr=False)  # each force's link (`compile`)

    name = "gravcomp"

    def compile(self, compilation: Compilation) -> None:
        self.links = [compilation.layout.links[art][link] for art, link, _ in self.forces]

    def apply(self, articulations) -> None:
        links = self.links or [articulations[art].links[link] for art, link, _ in self.forces]
        zero = np.zeros(3)
        for link, (_, _, force) in zip(links, self.forces):
            link.add_force_torque(force, zero)


def map_gravcomp(model: mujoco.MjModel, mapping: Mapping, articulations, notes: Notes) -> GravityCompensation | None:
    """Links of fully compensated bodies stop feeling gravity; the others get their per-step force."""
    gravity = np.asarray(model.opt.gravity, np.float64)
    if not np.any(model.body_gravcomp) or mj.disabled(model, "gravity") or not np.any(gravity):
        return None
    if np.any(model.jnt_actgravcomp):
        notes.approximate(
            "joint",
            "actuatorgravcomp",
            "gravity compensation routed through the actuators is "
            "applied as a passive force: the joint's actuatorfrcrange does not clamp it",
        )
    forces = []
    for b in range(1, model.nbody):
        share = float(model.body_gravcomp[b])
        target = mapping.bodies[b]
        if share == 0 or target is None or target.articulation is None:
            continue
        link = articulations[target.articulation].links[target.link]
        if share == 1.0:
            link.disable_gravity = True
        else:
            forces.append((target.articulation, target.link, -share * float(model.body_mass[b]) * gravity))
    return GravityCompensation(tuple(forces)) if forces else None
