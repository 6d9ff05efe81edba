"""Model features outside what this loader maps, found in the compiled model and named one by one."""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import Notes
from ..model import mj
from ..model.joints import is_limited

FLOAT32_CONDITION = 1e8  # a joint-space inertia conditioned worse leaves float32 (7 digits) no digit to solve with


def note_ill_conditioned(model: mujoco.MjModel, notes: Notes) -> None:
    """MuJoCo factorises the joint-space inertia in float64; PhysX's articulation solve is float32. Two coaxial
    hinges with a weightless link between them make it near singular: MuJoCo follows such a model, PhysX cannot
    (tests/test_loader_structure.py::test_a_joint_space_inertia_float32_cannot_resolve_is_listed)."""
    blocks = [block for _, block in mj.inertia_blocks(model, mj.forward_at(model)) if block.size]
    condition = max((float(np.linalg.cond(block)) for block in blocks), default=0.0)  # PhysX solves tree by tree
    if condition > FLOAT32_CONDITION:
        notes.approximate(
            "joint",
            "joint-space inertia",
            f"condition number {condition:.2g} at qpos0, beyond what "
            "PhysX's float32 articulation solve resolves: its dynamics cannot follow MuJoCo's",
        )


def find_unmapped(model: mujoco.MjModel, notes: Notes) -> None:
    """Every element and option the loader does not map, or maps approximately, noted once per load."""
    note_ill_conditioned(model, notes)
    _elements(model, notes)
    _options(model, notes)


def _elements(model: mujoco.MjModel, notes: Notes) -> None:
    """Flexes, plugins, mocap bodies, nonlinear joint terms and actuator passive terms."""
    for i in range(model.nflex):
        notes.drop("flex", f"flex{i}", "deformable (flex) objects have no PhysX articulation equivalent")
    for i in range(model.nplugin):
        notes.drop("plugin", f"plugin{i}", "engine plugins (sdf, elasticity, ...) cannot run inside PhysX")
    for b in np.flatnonzero(model.body_mocapid >= 0).tolist():
        notes.approximate("body", mj.name(model, "body", b), "mocap body loaded as a fixed link at its initial pose")
    nonlinear = np.any(model.jnt_stiffnesspoly != 0, axis=1)
    nonlinear[model.dof_jntid[np.any(model.dof_dampingpoly != 0, axis=1)]] = True
    for j in np.flatnonzero(nonlinear).tolist():
        notes.drop(
            "joint",
            mj.name(model, "joint", j),
            "nonlinear (polynomial) stiffness or damping: only the linear term is mapped",
        )
    passive = (model.actuator_damping != 0) | np.any(model.actuator_dampingpoly != 0, axis=1)
    for a in np.flatnonzero(passive | (model.actuator_armature != 0)).tolist():
        notes.drop(
            "actuator",
            mj.name(model, "actuator", a),
            "actuator damping/armature (passive terms on the transmission) are not mapped",
        )


def _options(model: mujoco.MjModel, notes: Notes) -> None:
    """Limits, the integrator and the model's contact and limit flags."""
    limited = sum(is_limited(model, j) for j in range(model.njnt))
    if limited and not mj.disabled(model, "limit", "constraint"):
        notes.approximate(
            "joint limits",
            f"{limited} joint{'s' if limited > 1 else ''}",
            "MuJoCo's soft limit rows, solved at SAPIEN's state by set_ctrl every step (runtime/rows.py); after "
            "release(), PhysX's rigid limits at the range",
        )
    integrator = int(model.opt.integrator)
    if integrator == int(mujoco.mjtIntegrator.mjINT_RK4):
        notes.approximate(
            "option",
            "integrator",
            "RK4 has no PhysX counterpart: simulated as MuJoCo's Euler "
            "(semi-implicit), first order in the timestep apart over a fixed time",
        )
    elif integrator == int(mujoco.mjtIntegrator.mjINT_IMPLICIT):
        notes.approximate(
            "option",
            "integrator",
            "implicit's Coriolis and actuator-gain derivatives are not "
            "mapped: simulated as MuJoCo's implicitfast, first order in the timestep apart over a fixed time",
        )
    if mj.disabled(model, "contact", "constraint"):
        notes.approximate("option", "flag contact", "contacts disabled in the model: every shape's groups are 0")
    if mj.disabled(model, "limit", "constraint"):
        notes.approximate("option", "flag limit", "limits disabled in the model: every joint is unlimited")
