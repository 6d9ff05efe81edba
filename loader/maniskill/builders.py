"""ManiSkill's scene builders with the loader's shapes and PhysX settings: one build makes the articulation in every
sub-scene (`set_scene_idxs`), each with the model's inertia, collision groups, joint frames, armature, damping and
PhysX overrides (tests/test_maniskill.py::test_an_arm_and_a_quadruped_load_into_a_maniskill_scene_as_in_mujoco)."""

from __future__ import annotations

import sapien
from mani_skill.utils.building.actor_builder import ActorBuilder
from mani_skill.utils.building.articulation_builder import ArticulationBuilder

from ..plan import physx_settings
from ..plan.builders import ShapesFromPlans, TreeOfPlannedLinks


class SceneActorBuilder(ShapesFromPlans, ActorBuilder):
    """The world body's static geoms, built in every sub-scene."""

    def __init__(self):
        super().__init__()
        self.shape_plans = []
        self.mesh_visuals = []
        self.initial_pose = sapien.Pose()  # the world body's frame

    def build_entity(self):
        entity = super().build_entity()  # ManiSkill's renders only visual records and procedural shapes
        if self.scene.can_render() and self.mesh_visuals and not (self.visual_records or self._procedural_shapes):
            entity.add_component(self.build_render_component())
        return entity


class SceneArticulationBuilder(TreeOfPlannedLinks, ArticulationBuilder):
    """One kinematic tree. `build()` makes it in each sub-scene, sets the loader's PhysX settings on each copy and
    then calls `on_built(builder, articulation)` (the loader plans each sub-scene's per-step terms there)."""

    def __init__(self):
        super().__init__()
        self.built: list[tuple[sapien.Scene, sapien.physx.PhysxArticulation]] = []  # of the last build
        self.on_built = None

    def _build_entities(self, fix_root_link=None, name_prefix="", initial_pose=None):
        entities = super()._build_entities(
            fix_root_link=fix_root_link,
            name_prefix=name_prefix,
            initial_pose=sapien.Pose() if initial_pose is None else initial_pose,
        )
        for builder, entity in zip(self.link_builders, entities):  # ManiSkill's renders only visual records
            if self.scene.can_render() and builder.mesh_visuals and not builder.visual_records:
                entity.add_component(builder.build_render_component())
        root = entities[0].find_component_by_type(sapien.physx.PhysxArticulationLinkComponent)
        self.built.append(root.articulation)
        return entities

    def build(self, name=None, fix_root_link=None, build_mimic_joints=True):
        self.built = []
        articulation = super().build(name=name, fix_root_link=fix_root_link, build_mimic_joints=build_mimic_joints)
        plans = [b.plan for b in self.link_builders]
        sub_scenes = [
            self.scene.sub_scenes[0 if self.scene.parallel_in_single_scene else int(i)] for i in self.scene_idxs
        ]
        for physx_articulation in self.built:
            physx_settings.apply_articulation_settings(physx_articulation, plans, self.timestep)
            if self.solver_iterations is not None:
                (physx_articulation.solver_position_iterations, physx_articulation.solver_velocity_iterations) = (
                    self.solver_iterations
                )
        self.built = list(zip(sub_scenes, self.built))
        if self.on_built is not None:
            self.on_built(self, articulation)
        return articulation
