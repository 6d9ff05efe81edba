"""SAPIEN builders that build completely on their own: in-memory meshes, per-shape collision groups and the
PhysX settings that make SAPIEN behave like MuJoCo, all applied inside `.build()`."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sapien
from sapien.wrapper.actor_builder import ActorBuilder
from sapien.wrapper.articulation_builder import ArticulationBuilder, LinkBuilder

from . import hulls
from . import physx_settings as physx
from .geom import ShapePlan
from .tree import LinkPlan
from .visual import attach_mesh_visuals


@lru_cache(maxsize=256)
def _material(friction: float) -> sapien.physx.PhysxMaterial:
    return sapien.physx.PhysxMaterial(friction, friction, 0.0)


def make_shape(plan: ShapePlan, dynamic: bool) -> sapien.physx.PhysxCollisionShape:
    material = _material(plan.friction)
    if plan.kind == "sphere":
        shape = sapien.physx.PhysxCollisionShapeSphere(radius=float(plan.size[0]), material=material)
    elif plan.kind == "box":
        shape = sapien.physx.PhysxCollisionShapeBox(half_size=np.asarray(plan.size, np.float32), material=material)
    elif plan.kind == "capsule":
        shape = sapien.physx.PhysxCollisionShapeCapsule(
            radius=float(plan.size[0]), half_length=float(plan.size[1]), material=material
        )
    elif plan.kind == "cylinder":
        shape = sapien.physx.PhysxCollisionShapeCylinder(
            radius=float(plan.size[0]), half_length=float(plan.size[1]), material=material
        )
    elif plan.kind == "plane":
        shape = sapien.physx.PhysxCollisionShapePlane(material=material)
    elif plan.kind == "convex":
        shape = hulls.convex_shape(plan.vertices, plan.scale, material, plan.mesh_key, plan.shared)
    elif plan.kind == "triangles" and not dynamic:
        shape = hulls.triangle_shape(plan.vertices, plan.triangles, np.ones(3, np.float32), material)
    elif plan.kind == "triangles":
        shape = sapien.physx.PhysxCollisionShapeTriangleMesh(
            np.ascontiguousarray(plan.vertices, np.float32),
            np.ascontiguousarray(plan.triangles, np.uint32),
            np.ones(3, np.float32),
            material,
            sdf=True,
        )
    else:
        raise ValueError(f"unknown shape kind {plan.kind!r}")
    shape.local_pose = plan.pose
    shape.set_collision_groups([int(x) & 0xFFFFFFFF for x in plan.groups])
    # a static shape (a floor, a table) keeps SAPIEN's offset: only a moving part's pairs are shrunk. PhysX needs the
    # contact offset above the rest offset: it is kept that far beyond it
    offset = physx.CONTACT_OFFSET if dynamic else shape.contact_offset
    shape.contact_offset = max(offset, plan.rest_offset + physx.CONTACT_OFFSET)
    shape.rest_offset = plan.rest_offset
    shape.min_patch_radius = plan.torsion
    return shape


class ShapesFromPlans:
    """Mixin: attach the planned collision shapes (primitives and in-memory meshes) with their own groups,
    and in-memory visual meshes."""

    shape_plans: list[ShapePlan]
    mesh_visuals: list

    def has_visuals(self) -> bool:
        return bool(self.visual_records or self.mesh_visuals)

    def build_render_component(self):
        component = super().build_render_component()
        attach_mesh_visuals(component, self.mesh_visuals)
        return component

    def build_physx_component(self, link_parent=None):
        component = super().build_physx_component(link_parent)
        dynamic = self.physx_body_type != "static"
        for plan in self.shape_plans:
            component.attach(make_shape(plan, dynamic))
        if not self._auto_inertial and dynamic:
            # attaching shapes may recompute mass properties: the model's inertial is authoritative
            component.mass = self._mass
            component.cmass_local_pose = self._cmass_local_pose
            component.inertia = self._inertia
        return component


class MJCFActorBuilder(ShapesFromPlans, ActorBuilder):
    """Static actor for the world body's geoms."""

    def __init__(self):
        super().__init__()
        self.shape_plans = []
        self.mesh_visuals = []

    def build_entity(self):
        entity = sapien.Entity()
        if self.has_visuals():
            entity.add_component(self.build_render_component())
        entity.add_component(self.build_physx_component())
        entity.name = self.name
        return entity


class MJCFLinkBuilder(ShapesFromPlans, LinkBuilder):
    def __init__(self, index: int, parent):
        super().__init__(index, parent)
        self.shape_plans = []
        self.mesh_visuals = []
        self.plan: LinkPlan | None = None


class TreeOfPlannedLinks:
    """What an articulation builder of the loader adds to SAPIEN's or ManiSkill's: links that carry their plans,
    and the settings `build()` applies (mixed in before either builder class)."""

    def __init__(self):
        super().__init__()
        self.floating = False
        self.timestep = 0.002  # the scene's, set by the loader: drives compensate MuJoCo's explicit terms
        self.solver_iterations: tuple[int, int] | None = None  # (position, velocity); None keeps PhysX's

    def create_link_builder(self, parent: MJCFLinkBuilder | None = None) -> MJCFLinkBuilder:
        if self.link_builders:
            assert parent is not None and parent in self.link_builders
        builder = MJCFLinkBuilder(len(self.link_builders), parent)
        self.link_builders.append(builder)
        return builder


class MJCFArticulationBuilder(TreeOfPlannedLinks, ArticulationBuilder):
    """One kinematic tree. `build()` also sets armature, damping, springs and the PhysX overrides."""

    def __init__(self):
        super().__init__()
        self.name = ""

    def build_entities(self, fix_root_link=None):
        entities = super().build_entities(fix_root_link=fix_root_link)
        for builder, entity in zip(self.link_builders, entities):
            if builder.mesh_visuals and not builder.visual_records:
                entity.add_component(builder.build_render_component())
        return entities

    def build(self, fix_root_link=None, build_mimic_joints=True) -> sapien.physx.PhysxArticulation:
        articulation = super().build(fix_root_link=fix_root_link, build_mimic_joints=build_mimic_joints)
        articulation.name = self.name
        physx.apply_articulation_settings(articulation, [b.plan for b in self.link_builders], self.timestep)
        if self.solver_iterations is not None:
            articulation.solver_position_iterations, articulation.solver_velocity_iterations = self.solver_iterations
        return articulation
