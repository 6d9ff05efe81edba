"""PhysX settings that differ from MuJoCo's behaviour (link damping, joint friction, speed caps, sleeping,
depenetration, the TGS solver), set so that SAPIEN simulates what MuJoCo does. Derivation:
docs/mapping.md#physx-settings.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import sapien

from ..errors import SceneMismatchWarning
from ..model import drive, mj
from ..model.drive import DofDrive
from ..model.joints import mujoco_coordinates
from ..model.options import MAX_DEPENETRATION_VELOCITY

MAX_LINK_LINEAR_VELOCITY = 1e4  # m/s
MAX_LINK_ANGULAR_VELOCITY = 1e4  # rad/s
MAX_JOINT_VELOCITY = 1e4

# m, the PhysX contact offset of every shape on a moving body: PhysX makes a contact between two shapes within the
# sum of theirs, MuJoCo only where they touch (within their margin). At SAPIEN's default of 0.01 every pair of a
# hand's fingers, 1.5 cm apart, is a contact, and the Menagerie LEAP hand under a ctrl walk at 100 Hz blows up on
# them within a control step (at 0.005 too); at 0.002 it holds, under PGS and TGS
# (tests/test_contact_classes.py::test_a_hand_under_a_ctrl_walk_at_100_hz_holds_its_fingers_apart). Static shapes
# (floors, tables) keep SAPIEN's: shrinking theirs too moved the corpus's settled poses on floors away from MuJoCo's
# (a humanoid's by 3 cm under ctrl), keeping them moved as many closer as away (mujoco 3.17.0, sapien 3.0.3)
CONTACT_OFFSET = 0.002


def matched_config(model: mujoco.MjModel) -> sapien.physx.PhysxSceneConfig:
    """The PhysX scene configuration matched to `model`: MuJoCo's gravity (zero where disabled) and PGS, not TGS
    (TGS adds a gap of order dt to MuJoCo's semi-implicit Euler)."""
    config = sapien.physx.get_scene_config()
    config.gravity = mj.gravity(model).astype(np.float32)
    config.enable_tgs = False
    return config


def create_scene(model: mujoco.MjModel) -> sapien.Scene:
    """A CPU PhysX scene with gravity, solver and timestep matched to `model` (and a render system where a
    render device exists, so that visual shapes can be added).

    SAPIEN 3.0 reads a system's gravity and solver only from the process-global scene configuration, when the system
    is created: it is set for that moment and restored right after, so scenes the caller creates later are as they
    would have been (tests/test_loader_scene.py::test_the_loader_leaves_physx_global_configuration_as_it_found_it).
    Sleeping is switched off per articulation (`apply_articulation_settings`), not globally.
    """
    from .visual import has_render_device

    previous = sapien.physx.get_scene_config()
    sapien.physx.set_scene_config(matched_config(model))
    try:
        systems = [sapien.physx.PhysxCpuSystem()]
    finally:
        sapien.physx.set_scene_config(previous)
    if has_render_device():
        systems.append(sapien.render.RenderSystem())
    scene = sapien.Scene(systems)
    scene.timestep = float(model.opt.timestep)
    return scene


def matched_scene(scene: sapien.Scene | None, model: mujoco.MjModel, path) -> sapien.Scene:
    """`scene`, with a SceneMismatchWarning for each way it simulates differently from `model`; without one, a scene
    matched to the model (`create_scene`)."""
    if scene is None:
        return create_scene(model)
    for mismatch in scene_mismatches(scene, model):
        warnings.warn(
            f"{path}: the scene given with set_scene differs from the model: {mismatch}",
            SceneMismatchWarning,
            stacklevel=5,
        )
    return scene


def scene_timestep(scene: sapien.Scene, model: mujoco.MjModel) -> float:
    """The timestep the per-step mapping uses: the scene's. PhysX stores it as float32, so a scene holding the
    model's timestep rounded to float32 runs the model's own (float64) one."""
    if np.float32(scene.timestep) == np.float32(model.opt.timestep):
        return float(model.opt.timestep)
    return float(scene.timestep)


def scene_config(scene: sapien.Scene):
    """The PhysX configuration the scene's system was created with (None where SAPIEN does not say)."""
    system = getattr(scene, "physx_system", None) or getattr(scene, "px", None)  # a scene of sub-scenes: `px`
    return getattr(system, "config", None)


def uses_tgs(scene: sapien.Scene) -> bool:
    """Whether the scene's PhysX solver is TGS (the per-step terms then write the drives as joint forces)."""
    config = scene_config(scene)
    return bool(config is not None and config.enable_tgs)


def scene_mismatches(scene: sapien.Scene, model: mujoco.MjModel) -> list[str]:
    """What a caller's scene sets differently from what MuJoCo simulates, each with what to set: the timestep,
    gravity and the solver (tests/test_loader_scene.py::test_a_scene_with_another_timestep_is_warned_and_used)."""
    out = []
    if scene_timestep(scene, model) != float(model.opt.timestep):
        out.append(
            f"its timestep is {scene.timestep:g} s, the model's {model.opt.timestep:g} s: the loader maps "
            "drives, actuators and constraint rows for the scene's timestep, so the motion is MuJoCo's at "
            "that timestep, not the file's (set scene.timestep to keep the file's)"
        )
    config = scene_config(scene)
    if config is None:
        return out
    wanted = matched_config(model)
    if not np.allclose(np.asarray(config.gravity), np.asarray(wanted.gravity), rtol=0.0, atol=1e-6):
        out.append(
            f"its gravity is {np.asarray(config.gravity).tolist()}, the model's {wanted.gravity.tolist()} "
            "(sapien.physx.set_scene_config(gravity=...) before creating the scene's PhysX system)"
        )
    if config.enable_tgs and not mujoco_coordinates(model):
        out.append(
            "it uses PhysX's TGS solver, whose drives do not step as MuJoCo's, and the model's ball joints keep "
            "them (sapien.physx.set_scene_config(enable_tgs=False) before creating the scene's PhysX system)"
        )
    return out


def apply_articulation_settings(articulation: sapien.physx.PhysxArticulation, plans, timestep: float) -> None:
    """Joint armature, damping and springs from the plans, and the PhysX overrides, on a built articulation."""
    articulation.set_sleep_threshold(0.0)
    by_name = {plan.name: plan for plan in plans}  # by entity name: a scene of sub-scenes prefixes the links' own
    for link in articulation.links:
        link.linear_damping = 0.0
        link.angular_damping = 0.0
        link.max_linear_velocity = MAX_LINK_LINEAR_VELOCITY
        link.max_angular_velocity = MAX_LINK_ANGULAR_VELOCITY
        link.max_depenetration_velocity = MAX_DEPENETRATION_VELOCITY
        joint = link.joint
        plan = by_name[link.entity.name].joint
        if joint.dof == 0:
            continue
        joint.set_friction(0.0)
        joint.set_max_velocity(MAX_JOINT_VELOCITY)
        joint.set_armature(np.array([plan.armature], np.float32))
        passive = DofDrive(plan.stiffness, plan.damping)
        drive.apply(joint, passive, plan.stiffness * plan.spring_target, timestep)
