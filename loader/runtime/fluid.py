"""MuJoCo's inertia-box fluid model (`<option density viscosity wind>`) as per-step link forces: viscous and
quadratic drag and torque on each body's equivalent box, from its velocity relative to the wind at the start of
the step, added once per step. Derivation: docs/mapping.md#fluid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..build.compile import MJMINVAL
from ..build.mapping import Mapping
from ..errors import Notes


@dataclass(frozen=True)
class FluidBody:
    articulation: int
    link: int
    box: tuple[float, float, float]  # sides of the equivalent inertia box


@dataclass(frozen=True)
class Fluid:
    density: float
    viscosity: float
    wind: np.ndarray
    bodies: tuple[FluidBody, ...]
    applied: list = field(default_factory=list)  # this step's (articulation, centre of mass, force, torque), world

    def wrench(self, box, angular: np.ndarray, linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo's fluid (torque, force) on a body, all in its inertial frame, from its velocity there."""
        b = np.asarray(box)
        diameter = b.mean()
        torque = -np.pi * diameter**3 * self.viscosity * angular
        force = -3.0 * np.pi * diameter * self.viscosity * linear
        if self.density > 0:
            area = np.array([b[1] * b[2], b[0] * b[2], b[0] * b[1]])
            force = force - 0.5 * self.density * area * np.abs(linear) * linear
            lever = np.array([b[0] * (b[1]**4 + b[2]**4), b[1] * (b[0]**4 + b[2]**4), b[2] * (b[0]**4 + b[1]**4)])
            torque = torque - self.density * lever * np.abs(angular) * angular / 64.0
        return torque, force

    name = "fluid"

    def contribute(self, step) -> None:
        """Link forces accumulate in PhysX until the step: added once per physics step."""
        if step.advance:
            self.apply(step.articulations)

    def velocity_links(self, articulations) -> list:
        return [articulations[b.articulation].links[b.link] for b in self.bodies]

    def apply(self, articulations) -> None:
        """Add this step's fluid force and torque at every body's centre of mass (once per step)."""
        self.applied.clear()
        for body in self.bodies:
            link = articulations[body.articulation].links[body.link]
            frame = (link.entity_pose * link.cmass_local_pose).to_transformation_matrix()[:3, :3]
            angular = frame.T @ np.asarray(link.angular_velocity, np.float64)
            linear = frame.T @ (np.asarray(link.linear_velocity, np.float64) - self.wind)
            torque, force = self.wrench(body.box, angular, linear)
            link.add_force_torque(frame @ force, frame @ torque)
            centre = (link.entity_pose * link.cmass_local_pose).p
            self.applied.append((body.articulation, np.asarray(centre, np.float64), frame @ force, frame @ torque))


def plan_fluid(model: mujoco.MjModel, mapping: Mapping, notes: Notes) -> Fluid | None:
    if model.opt.density <= 0 and model.opt.viscosity <= 0:
        return None
    ellipsoid = {int(model.geom_bodyid[g]) for g in range(model.ngeom) if model.geom_fluid[g, 0]}
    if ellipsoid:
        notes.drop("option", "fluidshape", "geoms with fluidshape=\"ellipsoid\" (MuJoCo's ellipsoid fluid model) "
                   "are not mapped; their bodies feel no fluid")
    if int(model.opt.integrator) != int(mujoco.mjtIntegrator.mjINT_EULER):
        notes.approximate("option", "density/viscosity", "fluid forces applied explicitly; this integrator also "
                          "treats their velocity derivatives implicitly (first order in the timestep apart)")
    bodies = []
    for b in range(1, model.nbody):
        target = mapping.bodies[b]
        mass = float(model.body_mass[b])
        if target is None or target.articulation is None or mass < MJMINVAL or b in ellipsoid:
            continue
        inertia = model.body_inertia[b]
        box = tuple(float(np.sqrt(max(MJMINVAL, inertia[j] + inertia[k] - inertia[i]) / mass * 6.0))
                    for i, j, k in ((0, 1, 2), (1, 0, 2), (2, 0, 1)))
        bodies.append(FluidBody(target.articulation, target.link, box))
    return Fluid(float(model.opt.density), float(model.opt.viscosity), np.asarray(model.opt.wind, np.float64),
                 tuple(bodies))
