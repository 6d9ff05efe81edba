"""Switching a loaded scene's collisions off and back on, in a way PhysX survives; and handing the contacts
between a load's own shapes to MuJoCo (`OwnContacts`)."""

from __future__ import annotations

from itertools import combinations

import sapien


def collision_shapes(result) -> list:
    """Every collision shape of a load result: articulation links' and static actors'."""
    return shapes_of(result.articulations, result.actors)


def shapes_of(articulations: list, actors: list) -> list:
    """Every collision shape of the links of `articulations` and of the actors (entities) `actors`."""
    components = [link for art in articulations for link in art.links]
    for entity in actors:
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


EVERY_BIT = 0xFFFFFFFF
LOAD_BITS = range(16, 31)  # the g1 bits a load's own shapes take sets of (`load_bits`)
LOAD_MASK = sum(1 << b for b in LOAD_BITS)


def external_only(groups: list[int], bits: int) -> list[int]:
    """A shape's collision groups that touch no shape of its own load (all carry g0 = every bit but `bits`, g1 =
    `bits`) and every other shape whose g1 has a bit outside `bits`: PhysX's rule `(g0a & g1b) or (g1a & g0b)`
    (docs/mapping.md#collision-filter). A shape that touches nothing keeps its groups; g2 and g3 (MuJoCo's body
    filter, ManiSkill's bits) stay."""
    if not (groups[0] or groups[1]):
        return list(groups)
    return [EVERY_BIT & ~bits, bits, int(groups[2]), int(groups[3])]


def scene_shapes(scene) -> list:
    """Every collision shape in `scene`: its actors' and its articulations' links'."""
    return [
        shape
        for entity in scene.entities
        for component in entity.components
        if isinstance(component, sapien.physx.PhysxRigidBaseComponent)
        for shape in component.collision_shapes
    ]


def taken_by_a_load(groups: list[int]) -> bool:
    """Whether a shape's words are a load's `external_only` ones: g1 a set of `LOAD_BITS`, g0 every other bit."""
    g0, g1 = int(groups[0]), int(groups[1])
    return bool(g1) and not g1 & ~LOAD_MASK and g0 == EVERY_BIT & ~g1


def load_bits(scene, own) -> int:
    """The set of `LOAD_BITS` (a mask) the load's own shapes take as g1 (`own`: the ids of the load's own shapes):
    the smallest, lowest first, of the bits no other shape carries in its g1, that no other load has taken. Two loads
    with sets A and B touch through PhysX: A's g0 meets B's g1 unless B lies within A, and the other way round, so
    only equal sets miss both; 15 free bits serve 2^15 - 1 loads
    (tests/test_loader_contact.py::test_loads_beyond_the_free_bits_still_touch_each_other)."""
    others, loads = 0, set()
    for shape in scene_shapes(scene):
        if id(shape) in own:
            continue
        groups = shape.get_collision_groups()
        if taken_by_a_load(groups):
            loads.add(int(groups[1]))
        else:
            others |= int(groups[1])
    free = [1 << b for b in LOAD_BITS if not others & (1 << b)]
    for size in range(1, len(free) + 1):
        for bits in combinations(free, size):
            if sum(bits) not in loads:
                return sum(bits)
    return 1 << LOAD_BITS[-1]  # every load bit in another shape's g1: the load touches what carries it


class OwnContacts:
    """The contacts between a load's own shapes (its bodies, its floor) as MuJoCo makes them: PhysX's between
    them are off while `take` holds (each shape's groups `external_only`), and MuJoCo's copy solves and applies
    them (`rows.py`); shapes of other loads and objects still touch the load through PhysX. `give_back` puts the
    load's own groups back, and PhysX's contacts with them (tests/test_loader_contact.py)."""

    def __init__(self, scene, shapes: list):
        self.scene, self.shapes = scene, shapes
        self.own: dict[int, list] | None = None  # while taken: the groups to give back, by id of the shape

    @property
    def taken(self) -> bool:
        return self.own is not None

    def groups(self, shape) -> list[int]:
        """`shape`'s own collision words (PhysX's filter of the model), also while taken."""
        if self.own is not None and id(shape) in self.own:
            return list(self.own[id(shape)])
        return list(shape.get_collision_groups())

    def take(self) -> None:
        if self.own is not None:
            return
        self.own = {id(shape): shape.get_collision_groups() for shape in self.shapes}
        bits = load_bits(self.scene, self.own)
        warm_up(self.scene)
        for shape in self.shapes:
            shape.set_collision_groups(external_only(self.own[id(shape)], bits))

    def give_back(self) -> None:
        if self.own is None:
            return
        warm_up(self.scene)
        for shape in self.shapes:
            shape.set_collision_groups(self.own[id(shape)])
        self.own = None
