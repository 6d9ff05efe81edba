"""MJCFLoader for a ManiSkill scene: the drop-in for `mani_skill.utils.building.mjcf_loader.MJCFLoader`.

The planning is the core loader's (`loader/mjcf_loader.py`); only the builders differ (`builders.py`), and links are
named, and ManiSkill's spellings read, as ManiSkill's own loader does (`maniskill_dialect`). On the CPU each sub-scene
also gets its own `LoadResult` (`results`): the mapping and the per-step terms that `set_ctrl` runs, which the
`mujoco_ctrl` controller drives; until it does, the joints are released (`LoadResult.release`: PhysX's hard limits at
MuJoCo's range), as ManiSkill's PD modes need them. On the GPU, PhysX holds the build-time settings by itself, and
the model's connects and welds as locked D6 joints (`lock_loops`); the per-step terms are not carried and one
`UnsupportedFeatureWarning` says so."""

from __future__ import annotations

import dataclasses
import warnings

from ..errors import UnsupportedFeatureWarning
from ..mjcf_loader import MJCFLoader as CoreLoader
from ..mjcf_loader import finish, lock_loops
from ..result import LoadResult
from .builders import SceneActorBuilder, SceneArticulationBuilder

SELF_COLLISION_BIT = 1 << 29  # ManiSkill's bit for "no collision with the same articulation" (group 2)
GPU_NOTE = (
    "per-step terms are CPU-only (the mujoco_ctrl mode; frictionloss, soft limits, clamps, tendons, joint "
    "couplings, connect and weld rows, fluid, gravcomp): on the GPU the robot has PhysX's joints, inertia, "
    "collision groups, armature, passive damping and limits, its connects and welds locked, driven by ManiSkill's "
    "PD controllers"
)


def per_step_terms(scene) -> bool:
    """Whether each sub-scene's load gets its `LoadResult` and per-step terms: on the CPU backend, where SAPIEN's state
    is read on the host; ManiSkill's GPU backend steps every sub-scene in one PhysX system on the device."""
    return not scene.gpu_sim_enabled


class MJCFLoader(CoreLoader):
    """ManiSkill's MJCF loader surface (`scene`, `name`, `disable_self_collisions`, `fix_root_link`,
    `ignore_classes`, `visual_groups`; `parse` returns ManiSkill's dict of builders; `load` returns ManiSkill's
    `Articulation`), building with the core loader's mapping in every sub-scene."""

    def __init__(self, ignore_classes: list[str] | None = None, visual_groups: list[int] | None = None):
        super().__init__(ignore_classes, visual_groups)
        self.name: str | None = None
        self.disable_self_collisions = False
        self.load_multiple_collisions_from_file = False  # ManiSkill's URDF option; MJCF meshes load as MuJoCo's
        self.maniskill_dialect = True  # ManiSkill's names (`dummy_root_<i>`) and spellings, as its tasks expect
        self.results: list[LoadResult] = []  # per sub-scene of the last build, CPU only
        self.standing_by: set[int] = set()  # the loops a law on the tensors holds: their D6 joints built free (GPU)

    def new_articulation_builder(self) -> SceneArticulationBuilder:
        return SceneArticulationBuilder()

    def new_actor_builder(self) -> SceneActorBuilder:
        return SceneActorBuilder()

    def parse(self, mjcf_file, package_dir=None) -> dict:
        """ManiSkill's `ParsedMJCFData`: `articulation_builders`, `actor_builders`, `cameras`; each builder builds
        in the sub-scenes `set_scene_idxs` names (all by default)."""
        parsed = self._parse(mjcf_file, package_dir)
        name = self.name if self.name is not None else parsed.tree.articulations[0].name
        builders = parsed.articulation_builders
        for i, builder in enumerate(builders):
            builder.set_name(f"{name}-articulation-{i}" if len(builders) > 1 else f"{name}")
            if self.disable_self_collisions:
                for link in builder.link_builders:
                    for plan in link.shape_plans:
                        plan.groups = [*plan.groups[:2], int(plan.groups[2]) | SELF_COLLISION_BIT, *plan.groups[3:]]
            builder.on_built = lambda built, articulation, parsed=parsed: self._plan_sub_scenes(parsed, built)
        for i, builder in enumerate(parsed.actor_builders):
            builder.set_name(f"{name}-actor-{i}")
        return {"articulation_builders": builders, "actor_builders": parsed.actor_builders, "cameras": parsed.cameras}

    def load(self, mjcf_file, package_dir=None, name=None, scene_idxs=None):
        """The model's first articulation, built in the sub-scenes `scene_idxs` (all by default), as ManiSkill's
        loader returns it; `results` holds each sub-scene's `LoadResult` (CPU)."""
        if name is not None:
            self.name = name
        builder = self.parse(mjcf_file, package_dir)["articulation_builders"][0]
        builder.set_scene_idxs(scene_idxs)
        return builder.build()

    def _plan_sub_scenes(self, parsed, built: SceneArticulationBuilder) -> None:
        self.results = []
        if not per_step_terms(self.scene):
            warnings.warn(f"{parsed.compiled.path}: {GPU_NOTE}", UnsupportedFeatureWarning, stacklevel=5)
            if len(parsed.articulation_builders) == 1:
                for sub_scene, articulation in built.built:
                    lock_loops(parsed, sub_scene, articulation, self.standing_by)
            return
        if len(parsed.articulation_builders) != 1:
            warnings.warn(
                f"{parsed.compiled.path}: the model has {len(parsed.articulation_builders)} kinematic trees; "
                "per-step terms need it to be one",
                UnsupportedFeatureWarning,
                stacklevel=5,
            )
            return
        alone = dataclasses.replace(parsed, actor_builders=[])  # the world's geoms are ManiSkill's business
        self.results = [
            finish(
                alone,
                sub_scene,
                [articulation],
                [],
                self.solver_iterations,
                self.warn_each_note,
                stacklevel=6,  # the caller of the builder's build()
                warn_approximations=self.warn_approximations,
                set_ctrl_law=self.set_ctrl_law,
            )
            for sub_scene, articulation in built.built
        ]
        for result in self.results:  # ManiSkill's PD modes drive PhysX alone; `mujoco_ctrl` takes the joints over
            result.release()
