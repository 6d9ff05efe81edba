"""PhysX settings that differ from MuJoCo's behaviour (link damping, joint friction, speed caps, sleeping,
depenetration, the TGS solver), set so that SAPIEN simulates what MuJoCo does. Derivation:
docs/mapping.md#physx-settings.
"""

from __future__ import annotations

import mujoco
import numpy as np
import sapien

from .. import drive, mj
from ..drive import DofDrive

MAX_LINK_LINEAR_VELOCITY = 1e4  # m/s
MAX_LINK_ANGULAR_VELOCITY = 1e4  # rad/s
MAX_JOINT_VELOCITY = 1e4
MAX_DEPENETRATION_VELOCITY = 0.1  # m/s; see docs/mapping.md#physx-settings and
# tests/test_loader_contact.py::test_arms_started_inside_each_other_come_apart_as_slowly_as_in_mujoco


def configure(model: mujoco.MjModel) -> None:
    """Process-global PhysX configuration matched to `model`; call before creating a PhysX system.

    PGS (not TGS): TGS adds a gap of order dt to MuJoCo's semi-implicit Euler.
    """
    gravity = np.zeros(3) if mj.disabled(model, "gravity") else model.opt.gravity
    sapien.physx.set_scene_config(gravity=np.asarray(gravity, np.float32), enable_tgs=False)
    sapien.physx.set_body_config(sleep_threshold=0.0)


def create_scene(model: mujoco.MjModel) -> sapien.Scene:
    """A CPU PhysX scene with gravity, solver and timestep matched to `model` (and a render system where a
    render device exists, so that visual shapes can be added)."""
    from .visual import has_render_device

    configure(model)
    systems = [sapien.physx.PhysxCpuSystem()]
    if has_render_device():
        systems.append(sapien.render.RenderSystem())
    scene = sapien.Scene(systems)
    scene.timestep = float(model.opt.timestep)
    return scene


def apply_articulation_settings(articulation: sapien.physx.PhysxArticulation, plans, timestep: float) -> None:
    """Joint armature, damping and springs from the plans, and the PhysX overrides, on a built articulation."""
    articulation.set_sleep_threshold(0.0)
    by_name = {plan.name: plan for plan in plans}
    for link in articulation.links:
        link.linear_damping = 0.0
        link.angular_damping = 0.0
        link.max_linear_velocity = MAX_LINK_LINEAR_VELOCITY
        link.max_angular_velocity = MAX_LINK_ANGULAR_VELOCITY
        link.max_depenetration_velocity = MAX_DEPENETRATION_VELOCITY
        joint = link.joint
        plan = by_name[link.name].joint
        if joint.dof == 0:
            continue
        joint.set_friction(0.0)
        joint.set_max_velocity(MAX_JOINT_VELOCITY)
        joint.set_armature(np.array([plan.armature], np.float32))
        passive = DofDrive(plan.stiffness, plan.damping)
        drive.apply(joint, passive, plan.stiffness * plan.spring_target, timestep)
