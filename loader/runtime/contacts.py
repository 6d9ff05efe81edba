"""Switching a loaded scene's collisions off and back on, in a way PhysX survives."""

from __future__ import annotations

import sapien


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
