"""MJCFLoader: the pipeline from an MJCF file to SAPIEN articulations and static actors.

compile (MuJoCo) -> plan the kinematic tree -> plan shapes and their collision filter -> builders -> build
-> mapping. Each stage lives in the module named after its MJCF concept.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import mujoco
import numpy as np
import sapien

from .errors import ControlError, Notes, warn_notes
from .model import mj
from .model.joints import FREE, KIND
from .model.mapping import BodyLink, GeomShape, JointDofs, Mapping
from .model.options import Options
from .plan import hulls, physx_settings
from .plan.actuators import map_actuators
from .plan.builders import MJCFActorBuilder, MJCFArticulationBuilder
from .plan.camera import CameraConfig, cameras, sites
from .plan.compile import CompiledModel, compile_mjcf
from .plan.contact import note_contact_laws, plan_collision_filter, plan_pairs
from .plan.equalities import map_equalities
from .plan.features import find_unmapped
from .plan.geom import collides, plan_shape
from .plan.numbers import check_numbers
from .plan.solver_iterations import tune_iterations
from .plan.texture import textures
from .plan.tree import TreePlan, plan_tree
from .plan.visual import add_visual, visuals_available
from .result import LoadResult
from .runtime.contacts import shapes_of
from .runtime.controller import Controller
from .runtime.controller import plan as runtime_plan
from .runtime.equalities import plan_equalities

CONTACTS = ("mujoco", "physx")  # whose the contacts between the model's own shapes are (`MJCFLoader.contacts`)
SET_CTRL_LAWS = ("mujoco_step", "terms")  # what gives `set_ctrl`'s joint forces (`MJCFLoader.set_ctrl_law`)


@dataclass
class _Parsed:
    compiled: CompiledModel
    tree: TreePlan
    articulation_builders: list[MJCFArticulationBuilder]
    actor_builders: list[MJCFActorBuilder]
    cameras: list[CameraConfig]
    notes: Notes


class MJCFLoader:
    """Load MJCF files into SAPIEN; the surface matches ManiSkill's MJCF loader.

    `ignore_classes`: geoms whose default class is listed are skipped entirely (ManiSkill's default: "motor").
    `visual_groups`: geom groups that become visual shapes where a render device exists (ManiSkill's: 0 and 2).
    `fix_root_link`: trees whose root has no free joint are fixed to the world (a free joint always floats).
    `solver_iterations`: "auto" (default) raises an articulation's PhysX position iterations until its joint
    drives converge (`plan/solver_iterations.py`); a (position, velocity) pair sets them; None keeps SAPIEN's
    (10, 1).
    `warn_each_note`: one UnsupportedFeatureWarning per note instead of one per kind with its count.
    `warn_approximations`: warn of the approximations too (they are always in `result.approximations`; what is
    dropped is always warned).
    `maniskill_dialect`: load as ManiSkill's own MJCF loader does: links named as it names them (`dummy_root_<i>`,
    `<body>_dummy_<k>`; `plan/tree.py`), and its spellings that MuJoCo rejects read with a note (`plan/dialect.py`);
    the ManiSkill drop-in sets it. Without it the loader loads what MuJoCo compiles and names links after bodies.
    `contacts`: "mujoco" (default): while `set_ctrl` runs, the contacts between the model's own shapes are MuJoCo's,
    solved by MuJoCo at SAPIEN's state and applied as forces, PhysX's between them off (shapes of other loads and
    objects still touch the model through PhysX); "physx": PhysX's rigid contacts (docs/mapping.md#contacts-as-rows).
    `set_ctrl_law`: "mujoco_step" (default): `set_ctrl`'s joint forces come from MuJoCo's own step at SAPIEN's
    state wherever every joint is a hinge or slide (`Controller.use_mujoco_step`), the per-step terms elsewhere;
    "terms": the terms everywhere (docs/architecture.md#mujocos-own-step).
    """

    def __init__(self, ignore_classes: list[str] | None = None, visual_groups: list[int] | None = None):
        self.ignore_classes = list(ignore_classes if ignore_classes is not None else ["motor"])
        self.visual_groups = list(visual_groups if visual_groups is not None else [0, 2])
        self.scene: sapien.Scene | None = None
        self.fix_root_link = True
        self.solver_iterations: tuple[int, int] | str | None = "auto"
        self.warn_each_note = False
        self.warn_approximations = False
        self.maniskill_dialect = False
        self.contacts = "mujoco"
        self.set_ctrl_law = "mujoco_step"

    def set_scene(self, scene: sapien.Scene) -> MJCFLoader:
        self.scene = scene
        return self

    def parse(self, mjcf_file: str | os.PathLike | mujoco.MjSpec, package_dir: str | os.PathLike | None = None):
        """Builders for `mjcf_file` (a path, or an `MjSpec` built or edited in Python): (articulation_builders,
        actor_builders, cameras).

        Each builder builds on its own with `.build()`. Without a scene, one matched to the model is created.
        """
        parsed = self._parse(mjcf_file, package_dir)
        return parsed.articulation_builders, parsed.actor_builders, parsed.cameras

    def load(
        self, mjcf_file: str | os.PathLike | mujoco.MjSpec, package_dir: str | os.PathLike | None = None
    ) -> LoadResult:
        """Build everything into `scene` and return it with the mapping and the unsupported features."""
        parsed = self._parse(mjcf_file, package_dir)
        articulations = [builder.build() for builder in parsed.articulation_builders]
        actors = [builder.build_static(builder.name) for builder in parsed.actor_builders]
        return finish(
            parsed,
            self.scene,
            articulations,
            actors,
            self.solver_iterations,
            self.warn_each_note,
            warn_approximations=self.warn_approximations,
            contacts=self.contacts,
            sole=True,
            set_ctrl_law=self.set_ctrl_law,
        )

    def new_articulation_builder(self) -> MJCFArticulationBuilder:
        """The builder of one kinematic tree (a subclass builds into a scene of sub-scenes: `loader.maniskill`)."""
        return MJCFArticulationBuilder()

    def new_actor_builder(self) -> MJCFActorBuilder:
        """The builder of the world body's static geoms."""
        return MJCFActorBuilder()

    def _parse(self, mjcf_file, package_dir) -> _Parsed:
        compiled = compile_mjcf(mjcf_file, package_dir, self.maniskill_dialect)
        with mj.sharing_qpos0(compiled.model, compiled.at_qpos0):
            return self._plan(compiled)

    def _plan(self, compiled: CompiledModel) -> _Parsed:
        model = compiled.model
        check_numbers(model, compiled.path)  # before anything is built: a failed load leaves the scene as it was
        self.scene = physx_settings.matched_scene(self.scene, model, compiled.path)  # warns where a given one differs
        tree = plan_tree(model, self.fix_root_link, self.maniskill_dialect)
        notes = tree.notes
        notes.extend(compiled.notes)
        find_unmapped(model, notes)
        geom_class = {g.id: g.classname.name for g in compiled.spec.geoms}
        kept = [g for g in range(model.ngeom) if geom_class.get(g) not in self.ignore_classes]
        static = {0} | ({b for b in range(model.nbody) if model.body_weldid[b] == 0} if self.fix_root_link else set())
        shapes = _shapes(model, tree, kept, static, notes)
        show = bool(self.visual_groups) and visuals_available(self.scene)
        visual = {g for g in kept if show and int(model.geom_group[g]) in self.visual_groups}
        dress = _Dresser(model, shapes, visual)
        articulation_builders = [self._articulation_builder(model, art, dress) for art in tree.articulations]
        actor_builders = [self._world_builder(dress)] if model.body_geomnum[0] else []
        return _Parsed(compiled, tree, articulation_builders, actor_builders, cameras(model), notes)

    def _articulation_builder(self, model: mujoco.MjModel, art, dress: _Dresser) -> MJCFArticulationBuilder:
        """One kinematic tree's builder: its links in order, each with its joint, inertia, shapes and visuals."""
        builder = self.new_articulation_builder()
        builder.set_scene(self.scene)
        builder.set_initial_pose(art.root_pose)
        builder.floating = art.floating
        builder.name = art.name
        builder.timestep = physx_settings.scene_timestep(self.scene, model)
        builder.solver_iterations = None if self.solver_iterations == "auto" else self.solver_iterations
        link_builders = []
        for link in art.links:
            lb = builder.create_link_builder(link_builders[link.parent] if link.parent is not None else None)
            lb.plan = link
            lb.set_name(link.name)
            lb.set_joint_name(link.joint.name)
            if link.parent is None:
                lb.joint_record.joint_type = link.joint.type
            else:
                joint = link.joint
                lb.set_joint_properties(
                    joint.type, [list(joint.limits)], link.pose_in_parent, joint.frame_in_child, 0.0, joint.damping
                )
            lb.set_mass_and_inertia(link.mass, link.cmass, np.asarray(link.inertia, np.float32))
            if link.body is not None:
                dress(lb, link.body)
            link_builders.append(lb)
        return builder

    def _world_builder(self, dress: _Dresser) -> MJCFActorBuilder:
        """The world body's static geoms as one static actor."""
        world = self.new_actor_builder()
        world.set_scene(self.scene)
        world.set_name("world")
        world.set_physx_body_type("static")
        dress(world, 0)
        return world


def _shapes(model: mujoco.MjModel, tree: TreePlan, kept: list[int], static: set[int], notes: Notes) -> dict:
    """Per colliding geom kept, its shape plan (geoms PhysX has no shape for are noted and left out), with the
    collision filter's groups (all zero where the model disables contacts)."""
    meshes: dict = {}
    shapes = {
        g: plan_shape(model, g, int(model.geom_bodyid[g]) in static, notes, meshes) for g in kept if collides(model, g)
    }
    shapes = {g: s for g, s in shapes.items() if s is not None}
    hulls.plan_sharing(shapes.values())
    contact_filter = plan_collision_filter(model, tree, {int(model.geom_bodyid[g]) for g in shapes}, static, notes)
    plan_pairs(model, tree, contact_filter, set(shapes), static, notes)
    contact_off = mj.disabled(model, "contact", "constraint")
    if not contact_off:
        note_contact_laws(model, shapes, static, notes)
    for g, shape in shapes.items():
        shape.groups = [0, 0, 0, 0] if contact_off else contact_filter.groups(model, g)
    return shapes


@dataclass
class _Dresser:
    """Puts a body's shapes and visuals on its builder."""

    model: mujoco.MjModel
    shapes: dict
    visual: set[int]

    def __call__(self, builder, body: int) -> None:
        model = self.model
        for g in range(model.body_geomadr[body], model.body_geomadr[body] + model.body_geomnum[body]):
            if g in self.shapes:
                builder.shape_plans.append(self.shapes[g])
            if g in self.visual:
                add_visual(builder, model, g)


def lock_loops(parsed: _Parsed, scene: sapien.Scene, articulation, standing_by: frozenset[int] = frozenset()) -> list:
    """The model's connects and welds on one built articulation (the model's only tree) as PhysX D6 joints locked as
    `release()` leaves them (`runtime/equalities.SoftConnect.lock`; idle where the equality starts inactive): what
    holds a closed loop, a gripper's linkage, where no per-step term runs (ManiSkill's GPU backend); those of
    `standing_by` (MuJoCo's ids) free, where a law on the tensors carries their rows
    (tests/test_maniskill.py::test_the_gpu_build_holds_a_closed_loop_with_locked_d6_joints)."""
    model = parsed.compiled.model
    mapping = _mapping(model, parsed, [articulation])
    links = map_equalities(model, scene, [articulation], mapping, Notes())
    laws = plan_equalities(model, links, physx_settings.scene_timestep(scene, model))
    for equality in set(standing_by) & laws.keys():  # a connect by site has no D6 joint
        laws[equality].stand_by()
    return list(laws.values())


def finish(
    parsed: _Parsed,
    scene: sapien.Scene,
    articulations: list,
    actors: list,
    solver_iterations: tuple[int, int] | str | None = "auto",
    warn_each_note: bool = False,
    stacklevel: int = 4,
    warn_approximations: bool = False,
    contacts: str = "mujoco",
    sole: bool = False,
    set_ctrl_law: str = "mujoco_step",
) -> LoadResult:
    """The mapping and the per-step terms of built articulations (one per tree, in order) in `scene`: the
    `LoadResult`, reset to qpos0. The notes are warned `stacklevel` frames up (default: `load`'s caller): what was
    dropped, and the approximations where `warn_approximations`; `contacts`: whose the model's own contacts are
    (`MJCFLoader`). `sole`: this is the parse's only build (not one sub-scene's of several), so the terms may keep
    its forward pass at qpos0 once the build has read it (`Controller.spare`); `set_ctrl_law`: what gives
    `set_ctrl`'s joint forces (`MJCFLoader`)."""
    if contacts not in CONTACTS:
        raise ControlError(f"contacts={contacts!r}: one of {', '.join(map(repr, CONTACTS))}")
    if set_ctrl_law not in SET_CTRL_LAWS:
        raise ControlError(f"set_ctrl_law={set_ctrl_law!r}: one of {', '.join(map(repr, SET_CTRL_LAWS))}")
    model = parsed.compiled.model
    mapping = _mapping(model, parsed, articulations)
    with mj.sharing_qpos0(model, parsed.compiled.at_qpos0):
        maps = map_actuators(model, mapping, parsed.notes)
        equalities = map_equalities(model, scene, articulations, mapping, parsed.notes)
        controller = _runtime(model, scene, articulations, actors, mapping, maps, equalities, parsed.notes, contacts)
        if solver_iterations == "auto":
            connects = [link.joint for link in equalities if link.kind == "D6 joint"]
            tune_iterations(articulations, model, controller.drive_weights(), connects, mapping, parsed.notes)
    if sole:
        controller.spare(model, parsed.compiled.at_qpos0)
    controller.mujoco_step = set_ctrl_law == "mujoco_step"
    result = LoadResult(
        path=str(parsed.compiled.path),
        spec=parsed.compiled.spec,
        scene=scene,
        articulations=articulations,
        actors=actors,
        cameras=parsed.cameras,
        sites=sites(model),
        textures=textures(parsed.compiled.spec, model),
        mapping=mapping,
        unsupported=list(parsed.notes.unsupported),
        approximations=list(parsed.notes.approximations),
        actuators=[entry for entry, _ in maps],
        equalities=equalities,
        controller=controller,
        replanner=replan,
        contacts=contacts,
    )
    approximations = result.approximations if warn_approximations else []
    warn_notes(result.path, result.unsupported, approximations, each=warn_each_note, stacklevel=stacklevel)
    result.reset()
    return result


def _runtime(
    model: mujoco.MjModel,
    scene: sapien.Scene,
    articulations: list,
    actors: list,
    mapping: Mapping,
    maps: list,
    equalities: list,
    notes: Notes,
    contacts: str,
) -> Controller:
    """The per-step terms of `model` (the runtime's own: nobody else edits it), at the scene's timestep; the model's
    own contacts MuJoCo's where `contacts` is "mujoco" (over the shapes of `articulations` and `actors`)."""
    options = Options.of(model, physx_settings.scene_timestep(scene, model), physx_settings.uses_tgs(scene))
    own = shapes_of(articulations, actors) if contacts == "mujoco" else None
    shapeless = [g for g, target in enumerate(mapping.geoms) if not _built(target, actors)]
    return runtime_plan(model, options, mapping, scene, articulations, maps, equalities, notes, own, shapeless)


def _built(target: GeomShape | None, actors: list) -> bool:
    """Whether a geom has a shape in SAPIEN: on a link, or on an actor that was built (the ManiSkill drop-in leaves
    the world's geoms to ManiSkill)."""
    if target is None:
        return False
    return target.articulation is not None or (target.actor is not None and target.actor < len(actors))


def replan(result: LoadResult, model: mujoco.MjModel) -> tuple[list, Controller]:
    """`LoadResult.replan`: the actuator maps and the per-step terms again from `model` (a copy of the caller's),
    with what the load built (mapping, articulations, equality joints) as it is. The result's notes stay the
    load's."""
    old = result.controller.model
    if (model.nq, model.nv, model.nu, model.neq, model.ntendon) != (old.nq, old.nv, old.nu, old.neq, old.ntendon):
        raise ControlError(f"{result.path}: the edited model has other elements than the loaded one; load it again")
    notes = Notes()
    maps = map_actuators(model, result.mapping, notes)
    controller = _runtime(
        model,
        result.scene,
        result.articulations,
        result.actors,
        result.mapping,
        maps,
        result.equalities,
        notes,
        result.contacts,
    )
    controller.mujoco_step = result.controller.mujoco_step  # the law the caller last chose
    return [entry for entry, _ in maps], controller


def _mapping(model: mujoco.MjModel, parsed: _Parsed, articulations) -> Mapping:
    """Where each MuJoCo body, joint and geom went among the built articulations and actors."""
    tree = parsed.tree
    link_index = []  # per articulation: link name -> index in art.links
    dof_index = []  # per articulation: child link name -> index in art.active_joints
    for art in articulations:
        link_index.append({link.entity.name: i for i, link in enumerate(art.links)})  # unprefixed in sub-scenes
        dof_index.append({joint.child_link.entity.name: i for i, joint in enumerate(art.active_joints)})
    bodies = [BodyLink(None, None, 0 if parsed.actor_builders else None)]
    for b in range(1, model.nbody):
        a, link = tree.body_link[b]
        bodies.append(BodyLink(a, link_index[a][tree.articulations[a].links[link].name]))
    joints = _joint_dofs(model, tree, dof_index)
    return Mapping.from_model(
        model, bodies, joints, _geom_shapes(model, parsed, link_index), [a.dof for a in articulations]
    )


def _joint_dofs(model: mujoco.MjModel, tree: TreePlan, dof_index: list[dict]) -> list[JointDofs]:
    """Per MuJoCo joint, its articulation and the SAPIEN DoFs its links' joints carry (none for a free joint)."""
    joint_links: dict[int, list[tuple[int, int]]] = {}
    for a, art in enumerate(tree.articulations):
        for link in art.links:
            if link.joint.mj_joint is not None:
                joint_links.setdefault(link.joint.mj_joint, []).append((a, dof_index[a][link.name]))
    joints = []
    for j in range(model.njnt):
        kind = KIND[int(model.jnt_type[j])]
        if int(model.jnt_type[j]) == FREE:
            joints.append(JointDofs(tree.body_link[int(model.jnt_bodyid[j])][0], kind, ()))
            continue
        targets = joint_links[j]
        joints.append(JointDofs(targets[0][0], kind, tuple(dof for _, dof in targets)))
    return joints


def _geom_shapes(model: mujoco.MjModel, parsed: _Parsed, link_index: list[dict]) -> list[GeomShape | None]:
    """Per MuJoCo geom, its collision shape on an articulation's link or on a static actor (None: no shape)."""
    geoms: list[GeomShape | None] = [None] * model.ngeom
    for a, builder in enumerate(parsed.articulation_builders):
        for lb in builder.link_builders:
            for s, shape in enumerate(lb.shape_plans):
                geoms[shape.geom] = GeomShape(a, link_index[a][lb.name], None, s)
    for a, builder in enumerate(parsed.actor_builders):
        for s, shape in enumerate(builder.shape_plans):
            geoms[shape.geom] = GeomShape(None, None, a, s)
    return geoms
