"""ManiSkill's own MJCF loader (`mani_skill.utils.building._mjcf_loader.MJCFLoader`) as a harness loader: what it
builds, shown to the tiers through a mapping made by MuJoCo names, so that the verdicts are about ManiSkill's loader.

It parses the file into a plain CPU SAPIEN scene (PhysX's CPU system, configured as ManiSkill's env configures it by
default but with MuJoCo's gravity and timestep and PGS, as the `maniskill` tier runs ManiSkill), and every
articulation and actor `parse` returns is built, as its own `load` does (ManiSkill's agent wrapper builds the first
articulation only). The mapping matches by name: a MuJoCo body to the link named after it, a hinge or slide to the
joint named after it, a free joint to the articulation's floating root when the body's link hangs on it by fixed
joints. What the loader loses, renames or leaves unnamed is unmapped, and the tiers report it (`structure`: no
link, not in the mapping); such a joint reads back at MuJoCo's qpos0, at rest. Its geoms carry no name, so no
collision shape is matched; it maps no actuator (the tiers it cannot take part in: `conformance.loaders.SKIPS`).

Without a render device ManiSkill's loader fails constructing render materials (`RenderMaterial`,
`RenderTexture2D`): there, and only there, an inert stand-in takes their place and SAPIEN's builders record no
visual; collision shapes, masses and joints are as the loader makes them."""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass

import mujoco
import numpy as np
import sapien

from loader import has_render_device
from loader.model.mapping import BodyLink, JointDofs
from loader.runtime import contacts

NAME = "maniskill"
_HINGE = {"revolute", "revolute_unwrapped", "continuous"}


class InertMaterial:
    """Stands in for `sapien.render.RenderMaterial` and `RenderTexture2D` without a render device: it keeps what it
    is given and renders nothing."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _inert_visual(self, *args, **kwargs):
    return self  # the builders' add_*_visual: nothing to render without a device


_VISUALS = (
    "add_box_visual",
    "add_capsule_visual",
    "add_cylinder_visual",
    "add_sphere_visual",
    "add_plane_visual",
    "add_visual_from_file",
)


@contextlib.contextmanager
def inert_rendering(module):
    """Inside: ManiSkill's loader module constructs `InertMaterial`s, and SAPIEN's builders record no visual."""
    from sapien.wrapper.actor_builder import ActorBuilder

    saved = {name: getattr(module, name) for name in ("RenderMaterial", "RenderTexture2D")}
    adders = {name: getattr(ActorBuilder, name) for name in _VISUALS}
    try:
        for name in saved:
            setattr(module, name, InertMaterial)
        for name in adders:
            setattr(ActorBuilder, name, _inert_visual)
        yield
    finally:
        for name, value in saved.items():
            setattr(module, name, value)
        for name, value in adders.items():
            setattr(ActorBuilder, name, value)


@contextlib.contextmanager
def maniskill_physx(model: mujoco.MjModel):
    """Inside: PhysX's process-wide configuration as ManiSkill's env sets it by default (`SceneConfig`,
    `DefaultMaterialsConfig`), but with MuJoCo's gravity and PGS; the previous configuration is put back after."""
    from mani_skill.utils.structs.types import DefaultMaterialsConfig, SceneConfig

    physx, config = sapien.physx, SceneConfig()
    saved = physx.get_scene_config(), physx.get_body_config(), physx.get_shape_config(), physx.get_default_material()
    gravity = np.zeros(3) if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY else model.opt.gravity
    try:
        physx.set_shape_config(contact_offset=config.contact_offset, rest_offset=config.rest_offset)
        physx.set_body_config(
            solver_position_iterations=config.solver_position_iterations,
            solver_velocity_iterations=config.solver_velocity_iterations,
            sleep_threshold=config.sleep_threshold,
        )
        physx.set_scene_config(
            gravity=np.asarray(gravity, dtype=np.float32),
            bounce_threshold=config.bounce_threshold,
            enable_pcm=config.enable_pcm,
            enable_tgs=False,
            enable_ccd=config.enable_ccd,
            enable_enhanced_determinism=config.enable_enhanced_determinism,
            enable_friction_every_iteration=config.enable_friction_every_iteration,
            cpu_workers=config.cpu_workers,
        )
        physx.set_default_material(**DefaultMaterialsConfig().dict())
        yield
    finally:
        scene, body, shape, material = saved
        physx.set_scene_config(scene)
        physx.set_body_config(body)
        physx.set_shape_config(shape)
        physx.set_default_material(material.static_friction, material.dynamic_friction, material.restitution)


@dataclass(frozen=True)
class Note:
    """One of ManiSkill's loader warnings, as the loader's notes are reported (kind, name, reason)."""

    kind: str
    name: str
    reason: str


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.notes: list[Note] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.notes.append(Note("maniskill", "", record.getMessage()))


def build(path: str, model: mujoco.MjModel):
    """ManiSkill's loader on `path` in a fresh scene: (scene, articulations, actors, its warnings as notes). Its
    logger's warnings are collected, not printed (the harness's terminal counts the notes per kind)."""
    from mani_skill import logger
    from mani_skill.utils.building import _mjcf_loader as module

    collect, propagate = _Collect(), logger.propagate
    handlers = list(logger.handlers)
    logger.handlers, logger.propagate = [collect], False
    try:
        with maniskill_physx(model), inert_rendering(module) if not has_render_device() else contextlib.nullcontext():
            scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
            scene.timestep = float(model.opt.timestep)
            loader = module.MJCFLoader()
            loader.set_scene(scene)
            articulation_builders, actor_builders, _ = loader.parse(str(path))
            articulations = [builder.build() for builder in articulation_builders]
            actors = [builder.build() for builder in actor_builders]
    finally:
        logger.handlers, logger.propagate = handlers, propagate
    return scene, articulations, actors, collect.notes


@dataclass
class FreeRoot:
    """A MuJoCo free joint carried by an articulation's floating root: its body's link hangs on the root by fixed
    joints at `offset` (the link's pose in the root's frame)."""

    articulation: int
    link: object
    offset: sapien.Pose


class NamedMapping:
    """MuJoCo <-> SAPIEN by names (`bodies`, `joints`, `geoms` as `loader.model.mapping.Mapping` has them, None where
    nothing matches) and the state conversion both ways. A joint SAPIEN does not carry reads back at MuJoCo's
    qpos0 and at rest; a free joint's body is placed through the root it hangs on."""

    def __init__(self, model: mujoco.MjModel, articulations):
        self.model = model
        links = {link.name: (a, i) for a, art in enumerate(articulations) for i, link in enumerate(art.links)}
        dofs = {
            joint.name: (a, d, joint.type)
            for a, art in enumerate(articulations)
            for d, joint in enumerate(art.active_joints)
            if joint.name
        }
        self.articulation_dofs = [art.dof for art in articulations]
        self.bodies = [BodyLink(None, None)] + [None] * (model.nbody - 1)
        for b in range(1, model.nbody):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
            if name in links:
                self.bodies[b] = BodyLink(*links[name])
        self.joints: list[JointDofs | None] = [None] * model.njnt
        self.free: dict[int, FreeRoot] = {}
        for j in range(model.njnt):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
            kind = int(model.jnt_type[j])
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                root = self._free_root(articulations, int(model.jnt_bodyid[j]))
                if root is not None:
                    self.free[j] = root
                    self.joints[j] = JointDofs(root.articulation, "free", ())
            elif name and name in dofs:
                a, d, sapien_type = dofs[name]
                self.joints[j] = JointDofs(a, "hinge" if sapien_type in _HINGE else "slide", (d,))
        self.geoms = [None] * model.ngeom

    def _free_root(self, articulations, body: int) -> FreeRoot | None:
        entry = self.bodies[body]
        if entry is None or entry.articulation is None:
            return None
        art = articulations[entry.articulation]
        link = art.links[entry.link]
        chain = link
        while chain.parent is not None:
            if chain.joint.type != "fixed":
                return None
            chain = chain.parent
        if chain.joint.type == "fixed":
            return None  # a fixed root: the free body cannot move
        art.set_qpos(np.zeros(art.dof, dtype=np.float32))
        return FreeRoot(entry.articulation, link, art.get_root_pose().inv() * link.entity_pose)

    def set_state(self, articulations, qpos, qvel=None) -> None:
        model = self.model
        qpos = np.asarray(qpos, dtype=np.float64)
        qvel = np.zeros(model.nv) if qvel is None else np.asarray(qvel, dtype=np.float64)
        q = [np.zeros(n) for n in self.articulation_dofs]
        v = [np.zeros(n) for n in self.articulation_dofs]
        for j, target in enumerate(self.joints):
            adr, dof = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            if j in self.free:
                self._set_root(articulations, self.free[j], qpos[adr : adr + 7], qvel[dof : dof + 6])
            elif target is not None:
                q[target.articulation][target.dofs[0]] = qpos[adr]
                v[target.articulation][target.dofs[0]] = qvel[dof]
        for art, qa, va in zip(articulations, q, v):
            art.set_qpos(qa.astype(np.float32))
            art.set_qvel(va.astype(np.float32))

    @staticmethod
    def _set_root(articulations, root: FreeRoot, qpos7, qvel6) -> None:
        art = articulations[root.articulation]
        body = sapien.Pose(qpos7[:3], qpos7[3:] / np.linalg.norm(qpos7[3:]))
        pose = body * root.offset.inv()
        omega = body.to_transformation_matrix()[:3, :3] @ qvel6[3:]
        com = (pose * art.root.cmass_local_pose).p
        art.set_root_pose(pose)
        art.set_root_linear_velocity((qvel6[:3] + np.cross(omega, com - qpos7[:3])).astype(np.float32))
        art.set_root_angular_velocity(omega.astype(np.float32))

    def get_state(self, articulations) -> tuple[np.ndarray, np.ndarray]:
        model = self.model
        qpos, qvel = model.qpos0.copy(), np.zeros(model.nv)
        q = [np.asarray(art.get_qpos(), np.float64) for art in articulations]
        v = [np.asarray(art.get_qvel(), np.float64) for art in articulations]
        for j, target in enumerate(self.joints):
            adr, dof = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            if j in self.free:
                root = self.free[j]
                art = articulations[root.articulation]
                pose = art.get_root_pose() * root.offset
                omega = np.asarray(art.get_root_angular_velocity(), np.float64)
                com = (art.get_root_pose() * art.root.cmass_local_pose).p
                v_com = np.asarray(art.get_root_linear_velocity(), np.float64)
                qpos[adr : adr + 7] = np.concatenate([pose.p, pose.q])
                qvel[dof : dof + 3] = v_com + np.cross(omega, pose.p - com)
                qvel[dof + 3 : dof + 6] = pose.to_transformation_matrix()[:3, :3].T @ omega
            elif target is not None:
                qpos[adr] = q[target.articulation][target.dofs[0]]
                qvel[dof] = v[target.articulation][target.dofs[0]]
        return qpos, qvel


class _Controller:
    """No per-step terms: ManiSkill's loader plans none."""

    @staticmethod
    def term(name, on=False):
        return None


@dataclass
class ManiSkillResult:
    """What the tiers read of a load (`loader.LoadResult`'s surface) for ManiSkill's loader: no actuators, no
    per-step terms; a generalized force is written to the joints the mapping carries (`set_qf`)."""

    path: str
    model: mujoco.MjModel
    scene: sapien.Scene
    articulations: list
    actors: list
    mapping: NamedMapping

    def __post_init__(self):
        self.controller = _Controller()
        self.actuators, self.unsupported, self.approximations, self.equalities = [], [], [], []
        self._saved_groups = None

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The live state in MuJoCo's layout, as far as the name mapping carries it."""
        return self.mapping.get_state(self.articulations)

    def set_state(self, qpos, qvel=None) -> None:
        self.mapping.set_state(self.articulations, qpos, qvel)

    def set_act(self, act) -> None:
        """No activation: ManiSkill's loader maps no actuators."""

    def disable_actuators(self, disabled: bool = True) -> None:
        """Nothing to disable: ManiSkill's loader maps no actuators."""

    def set_ctrl(self, ctrl, qfrc_applied=None, advance: bool = True) -> None:
        """`qfrc_applied` on the hinges and slides the mapping carries; ctrl has nothing to drive."""
        qf = [np.zeros(n) for n in self.mapping.articulation_dofs]
        if qfrc_applied is not None:
            for j, target in enumerate(self.mapping.joints):
                if target is not None and target.dofs:
                    qf[target.articulation][target.dofs[0]] = qfrc_applied[int(self.model.jnt_dofadr[j])]
        for art, forces in zip(self.articulations, qf):
            art.set_qf(forces.astype(np.float32))

    def set_contacts(self, enabled: bool) -> None:
        if not enabled and self._saved_groups is None:
            self._saved_groups = contacts.disable_contacts(self)
        elif enabled and self._saved_groups is not None:
            contacts.restore_contacts(self, self._saved_groups)
            self._saved_groups = None


def load(path: str) -> tuple[ManiSkillResult, mujoco.MjModel, float, float]:
    """(result, MuJoCo's model, MuJoCo's compile seconds, ManiSkill's load seconds)."""
    from mani_skill.utils.building import _mjcf_loader  # noqa: F401  imported before the load is timed

    t0 = time.perf_counter()
    model = mujoco.MjModel.from_xml_path(str(path))
    compile_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    scene, articulations, actors, notes = build(path, model)
    load_seconds = time.perf_counter() - t0
    result = ManiSkillResult(str(path), model, scene, articulations, actors, NamedMapping(model, articulations))
    result.unsupported = notes
    return result, model, compile_seconds, load_seconds
