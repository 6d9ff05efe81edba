"""MuJoCo's inertia-box fluid model (`<option density viscosity wind>`) as per-step link forces: viscous and
quadratic drag and torque on each body's equivalent box, from its velocity relative to the wind at the start of
the step, added once per step. The bodies' frames and velocities come from MuJoCo's kinematics at SAPIEN's state
(what the joint velocities imply, as MuJoCo's own fluid reads them), not from a SAPIEN read per link.
Derivation: docs/mapping.md#fluid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import Notes
from ..model.frames import cross_rows
from ..model.mapping import Mapping
from ..model.mj import MJMINVAL
from .dof_step import Step
from .term import Compilation, LinkForces


@dataclass(frozen=True)
class FluidBody:
    articulation: int
    link: int
    box: tuple[float, float, float]  # sides of the equivalent inertia box
    body: int  # MuJoCo's


@dataclass
class Fluid(LinkForces):
    density: float
    viscosity: float
    wind: np.ndarray
    bodies: tuple[FluidBody, ...]
    wrenches: list = field(default_factory=list)  # this step's (articulation, centre of mass, force, torque), world
    factors: np.ndarray | None = field(default=None, repr=False)  # `coefficients`, planned by `compile`
    links: list | None = field(default=None, repr=False)  # each body's link (`compile`)
    model: mujoco.MjModel | None = field(default=None, repr=False)  # the runtime's, for MuJoCo's kinematics
    mapping: Mapping | None = field(default=None, repr=False)
    data: mujoco.MjData | None = field(default=None, repr=False)  # made at first use unless the load's is spared

    def coefficients(self) -> np.ndarray:
        """Per body (rows), the state-independent factors of `wrench`'s four terms: viscous torque, viscous force,
        quadratic force (per axis), quadratic torque (per axis), as columns of width 1, 1, 3, 3."""
        b = np.array([body.box for body in self.bodies], dtype=np.float64).reshape(-1, 3)
        diameter = b.mean(axis=1)[:, None]
        area = np.stack([b[:, 1] * b[:, 2], b[:, 0] * b[:, 2], b[:, 0] * b[:, 1]], axis=1)
        lever = np.stack(
            [
                b[:, 0] * (b[:, 1] ** 4 + b[:, 2] ** 4),
                b[:, 1] * (b[:, 0] ** 4 + b[:, 2] ** 4),
                b[:, 2] * (b[:, 0] ** 4 + b[:, 1] ** 4),
            ],
            axis=1,
        )
        return np.concatenate(
            [
                -np.pi * diameter**3 * self.viscosity,
                -3.0 * np.pi * diameter * self.viscosity,
                0.5 * self.density * area,
                self.density * lever,
            ],
            axis=1,
        )

    def wrench(self, coefficients: np.ndarray, angular: np.ndarray, linear: np.ndarray):
        """MuJoCo's fluid (torque, force) on each body (rows), all in its inertial frame, from its velocity there."""
        torque = coefficients[:, 0:1] * angular
        force = coefficients[:, 1:2] * linear
        if self.density > 0:
            force = force - coefficients[:, 2:5] * np.abs(linear) * linear
            torque = torque - coefficients[:, 5:8] * np.abs(angular) * angular / 64.0
        return torque, force

    name = "fluid"

    @property
    def applied(self) -> list:
        return self.wrenches

    def compile(self, compilation: Compilation) -> None:
        self.factors = self.coefficients()
        self.links = [compilation.layout.links[body.articulation][body.link] for body in self.bodies]
        self.ids = np.array([body.body for body in self.bodies], dtype=int)
        self.roots = self.model.body_rootid[self.ids]  # each body's tree, at whose centre of mass MuJoCo takes cvel

    def spare(self, model, data) -> bool:
        if self.data is not None or model is not self.model:
            return False
        self.data = data
        return True

    def contribute(self, step: Step) -> None:
        if step.advance:
            self.push(step)

    def push(self, step: Step) -> None:
        """Add this step's fluid force and torque at every body's centre of mass (once per step), from MuJoCo's
        kinematics at the step's start: the rows' forward pass where it ran at this state, else this term's
        (tests/test_loader_passive.py::test_fluid_forces_match_mujoco)."""
        model, data = self.model, step.forwarded
        if data is None:
            if self.data is None:
                self.data = mujoco.MjData(model)
            data = self.data
            data.qpos[:], data.qvel[:] = step.mujoco_state(self.mapping)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_comVel(model, data)
        ids = self.ids
        centres = data.xipos[ids]
        frames = data.ximat[ids].reshape(-1, 3, 3)  # each body's inertial frame in the world
        velocity = data.cvel[ids]  # (angular, linear) at the tree's centre of mass
        angular = velocity[:, :3]
        linear = velocity[:, 3:] + cross_rows(angular, centres - data.subtree_com[self.roots]) - self.wind
        to_body = frames.transpose(0, 2, 1)
        torque, force = self.wrench(
            self.factors, (to_body @ angular[:, :, None])[:, :, 0], (to_body @ linear[:, :, None])[:, :, 0]
        )
        torque, force = (frames @ torque[:, :, None])[:, :, 0], (frames @ force[:, :, None])[:, :, 0]
        for link, f, t in zip(self.links, force, torque):
            link.add_force_torque(f, t)
        self.wrenches.clear()
        self.wrenches.extend(zip([body.articulation for body in self.bodies], centres.copy(), force, torque))


def plan_fluid(model: mujoco.MjModel, mapping: Mapping, notes: Notes) -> Fluid | None:
    if model.opt.density <= 0 and model.opt.viscosity <= 0:
        return None
    ellipsoid = {int(model.geom_bodyid[g]) for g in range(model.ngeom) if model.geom_fluid[g, 0]}
    if ellipsoid:
        notes.drop(
            "option",
            "fluidshape",
            'geoms with fluidshape="ellipsoid" (MuJoCo\'s ellipsoid fluid model) '
            "are not mapped; their bodies feel no fluid",
        )
    if int(model.opt.integrator) != int(mujoco.mjtIntegrator.mjINT_EULER):
        notes.approximate(
            "option",
            "density/viscosity",
            "fluid forces applied explicitly; this integrator also "
            "treats their velocity derivatives implicitly (first order in the timestep apart)",
        )
    bodies = []
    for b in range(1, model.nbody):
        target = mapping.bodies[b]
        mass = float(model.body_mass[b])
        if target is None or target.articulation is None or mass < MJMINVAL or b in ellipsoid:
            continue
        inertia = model.body_inertia[b]
        box = tuple(
            float(np.sqrt(max(MJMINVAL, inertia[j] + inertia[k] - inertia[i]) / mass * 6.0))
            for i, j, k in ((0, 1, 2), (1, 0, 2), (2, 0, 1))
        )
        bodies.append(FluidBody(target.articulation, target.link, box, b))
    if not bodies:  # no body the fluid acts on (every one massless, welded to the world or ellipsoid-shaped)
        return None
    return Fluid(
        float(model.opt.density),
        float(model.opt.viscosity),
        np.asarray(model.opt.wind, np.float64),
        tuple(bodies),
        model=model,
        mapping=mapping,
    )
