"""PhysX settings that differ from MuJoCo's behaviour, set so that SAPIEN simulates what MuJoCo does.

Measured (FACTS.md): PhysX damps links (0.05), adds joint friction (0.05), caps link speeds (10 m/s, 50 rad/s)
and joint speeds (100), puts slow bodies to sleep (0.005) and pushes penetrating bodies apart without limit.
MuJoCo does none of these.
"""

from __future__ import annotations

import mujoco
import numpy as np
import sapien

from . import drive, mj
from .drive import DofDrive

MAX_LINK_LINEAR_VELOCITY = 1e4  # m/s
MAX_LINK_ANGULAR_VELOCITY = 1e4  # rad/s
MAX_JOINT_VELOCITY = 1e4
MAX_DEPENETRATION_VELOCITY = 1.0  # m/s; MuJoCo's soft contacts never push harder than that at rest


def configure(model: mujoco.MjModel) -> None:
    """Process-global PhysX configuration matched to `model`; call before creating a PhysX system.

    PGS (not TGS): TGS adds an O(timestep) gap to MuJoCo's semi-implicit Euler (FACTS.md).
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


def refresh_link_velocities(articulations) -> None:
    """Make a fixed-base articulation's link velocities the ones its joint velocities imply.

    Measured, and PhysX's source says why: after a step, a fixed-base articulation's links keep the solver's
    velocities, which carry dt times each link's velocity-product acceleration on top of what the new joint
    velocities imply (1.4e-5 m/s on a slide of tests/fixtures/turning_slide.xml; the next step rebuilds them from
    the joint velocities, a floating base's are rebuilt at once). Per-step terms that read link velocities
    (connect and weld rows, fluid, slides) read them after this: the closed five-bar's rollouts 1.2e-5 -> 7.9e-7
    rad. Writing the joint velocities back leaves the dynamics as they are."""
    for articulation in articulations:
        if articulation.dof and articulation.root.joint.type == "fixed":
            articulation.set_qvel(articulation.get_qvel())


def collision_shapes(result) -> list:
    """Every collision shape of a load result: articulation links' and static actors'."""
    components = [link for art in result.articulations for link in art.links]
    for entity in result.actors:
        components.extend(c for c in entity.components if isinstance(c, sapien.physx.PhysxRigidBaseComponent))
    return [shape for component in components for shape in component.collision_shapes]


WARM_UP_TIMESTEP = 1e-12  # s: the step that lets PhysX survive a later restore of the collision groups


def warm_up(scene) -> None:
    """One PhysX step of `WARM_UP_TIMESTEP`, the whole PhysX state packed before and unpacked after."""
    system, timestep = scene.physx_system, scene.timestep
    state = system.pack()
    try:
        scene.timestep = WARM_UP_TIMESTEP
        scene.step()
    finally:
        scene.timestep = timestep
        system.unpack(state)


def disable_contacts(result) -> list:
    """Turn every collision shape of a load result off (contact-free comparisons); returns the groups to put back
    with `restore_contacts`. PhysX crashes (segmentation fault) when groups zeroed before a scene's first step are
    restored after stepping; a step of `WARM_UP_TIMESTEP` first prevents it, and the whole PhysX state is packed
    before it and unpacked after, so every body's state is bit for bit what it was; PhysX's solver caches are not
    (tests/test_loader_contact.py)."""
    shapes = collision_shapes(result)
    saved = [shape.get_collision_groups() for shape in shapes]
    warm_up(result.scene)
    for shape in shapes:
        shape.set_collision_groups([0, 0, 0, 0])
    return saved


def restore_contacts(result, saved: list) -> None:
    """Put back the collision groups `disable_contacts` returned."""
    for shape, groups in zip(collision_shapes(result), saved):
        shape.set_collision_groups(groups)
