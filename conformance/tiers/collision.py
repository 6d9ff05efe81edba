"""Tier 4: per geom, the collision shape PhysX really holds: type, size, world pose and collision groups."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from .. import sapien_side
from ..data_pool import borrowed
from ..reference import contacts_disabled
from ..report import Metric, TierReport, judged, metric
from ..sampling import line_angle, quaternion_angle
from ..tolerances import Tolerances

_G = mujoco.mjtGeom
_P = sapien.physx
EXACT = {
    _G.mjGEOM_PLANE: _P.PhysxCollisionShapePlane,
    _G.mjGEOM_SPHERE: _P.PhysxCollisionShapeSphere,
    _G.mjGEOM_CAPSULE: _P.PhysxCollisionShapeCapsule,
    _G.mjGEOM_CYLINDER: _P.PhysxCollisionShapeCylinder,
    _G.mjGEOM_BOX: _P.PhysxCollisionShapeBox,
    _G.mjGEOM_MESH: _P.PhysxCollisionShapeConvexMesh,
}
MESHLIKE = (_P.PhysxCollisionShapeConvexMesh, _P.PhysxCollisionShapeTriangleMesh)
_MAX_NOTES = 25


def _rotation(q_wxyz) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q_wxyz, dtype=float))
    return mat.reshape(3, 3)


def shape_world_vertices(component, shape) -> np.ndarray:
    pose = sapien_side.shape_world_pose(component, shape)
    verts = np.asarray(shape.get_vertices(), dtype=float) * np.asarray(shape.get_scale(), dtype=float)
    return verts @ _rotation(pose.q).T + np.asarray(pose.p, dtype=float)


def geom_world_aabb(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[np.ndarray, np.ndarray]:
    """World AABB of a geom's collision volume (mesh vertices, or the analytic primitive)."""
    rot = data.geom_xmat[g].reshape(3, 3)
    size = model.geom_size[g]
    kind = model.geom_type[g]
    if kind == _G.mjGEOM_MESH:
        m = model.geom_dataid[g]
        verts = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]]
        world = verts @ rot.T + data.geom_xpos[g]
        return world.min(axis=0), world.max(axis=0)
    if kind == _G.mjGEOM_HFIELD:  # the elevation surface PhysX meshes (no base below it)
        h = model.geom_dataid[g]
        nrow, ncol = model.hfield_nrow[h], model.hfield_ncol[h]
        sx, sy, sz, _ = model.hfield_size[h]
        elevation = model.hfield_data[model.hfield_adr[h] : model.hfield_adr[h] + nrow * ncol]
        xs, ys = np.meshgrid(np.linspace(-sx, sx, ncol), np.linspace(-sy, sy, nrow))
        local = np.stack([xs.ravel(), ys.ravel(), elevation * sz], axis=1)
        world = local @ rot.T + data.geom_xpos[g]
        return world.min(axis=0), world.max(axis=0)
    if kind == _G.mjGEOM_ELLIPSOID:
        half = np.sqrt(((rot * size[None, :]) ** 2).sum(axis=1))
    elif kind in (_G.mjGEOM_CYLINDER, _G.mjGEOM_CAPSULE):
        r, h = size[0], size[1]
        axis = rot[:, 2]
        half = np.abs(axis) * h + r * np.sqrt(np.clip(1 - axis**2, 0, 1))
        if kind == _G.mjGEOM_CAPSULE:
            half = np.abs(axis) * h + r
    elif kind == _G.mjGEOM_BOX:
        half = np.abs(rot) @ size
    else:  # sphere
        half = np.full(3, size[0])
    return data.geom_xpos[g] - half, data.geom_xpos[g] + half


@dataclass(frozen=True)
class _Groups:
    """What a shape's first two group words must hold: the geom's contype and conaffinity (0 with contacts off). A
    geom an explicit pair names (`paired`) may carry beside them bits no geom's contype or conaffinity uses
    (`spare`): the loader's pair bits. Read from the model once per tier run."""

    contact_off: bool
    paired: frozenset[int]
    spare: int

    @classmethod
    def of(cls, model: mujoco.MjModel, contact_off: bool) -> _Groups:
        used = 0
        for g in range(model.ngeom):
            used |= int(model.geom_contype[g]) | int(model.geom_conaffinity[g])
        paired = frozenset(int(g) for g in (*model.pair_geom1, *model.pair_geom2))
        return cls(contact_off, paired, ~used & 0xFFFFFFFF)

    def needs_shape(self, model: mujoco.MjModel, g: int) -> bool:
        """A geom MuJoCo may make a contact with: its bits, or an explicit pair naming it."""
        return bool(model.geom_contype[g] or model.geom_conaffinity[g]) or g in self.paired

    def wrong(self, model: mujoco.MjModel, g: int, name: str, held: list[int]) -> str | None:
        """What is wrong with the words `held` the shape of geom `g` carries, or None."""
        expected = [0, 0] if self.contact_off else [int(model.geom_contype[g]), int(model.geom_conaffinity[g])]
        groups = [x & ~self.spare for x in held] if g in self.paired and not self.contact_off else held
        if groups == expected:
            return None
        return f"{name}: groups {groups}, expected contype/conaffinity {expected}" + (
            " (contact disabled)" if self.contact_off else ""
        )


@dataclass
class _Findings:
    """What comparing geoms with their shapes gathers: problems, notes, the errors each metric judges, and how many
    shapes were compared."""

    mismatches: list[str] = field(default_factory=list)
    groups_wrong: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    size_err: list[float] = field(default_factory=list)
    pos_err: list[float] = field(default_factory=list)
    rot_err: list[float] = field(default_factory=list)
    mesh_err: list[float] = field(default_factory=list)
    approx_err: list[float] = field(default_factory=list)
    checked: int = 0


def collision(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    with borrowed(model) as data:
        mujoco.mj_kinematics(model, data)
        sapien_side.set_state(result, model.qpos0, np.zeros(model.nv))
        found = _Findings()
        groups = _Groups.of(model, contacts_disabled(model))
        for g in range(model.ngeom):
            _check_geom(result, model, data, g, groups, found)
        problems = found.mismatches + found.groups_wrong
        notes = problems[:_MAX_NOTES] + found.notes[:_MAX_NOTES]
        mismatches, groups_wrong, checked = len(found.mismatches), len(found.groups_wrong), found.checked
        metrics = [
            Metric("mismatches", float(mismatches), float(mismatches), 0.0, "count", model.ngeom),
            Metric("groups", float(groups_wrong), float(groups_wrong), 0.0, "count", checked),
            metric("size", found.size_err, tolerances["collision.size"], "m"),
            metric("position", found.pos_err, tolerances["collision.position"], "m"),
            metric("orientation", found.rot_err, tolerances["collision.orientation"], "rad"),
            metric("mesh_aabb", found.mesh_err, tolerances["collision.mesh_aabb"], "m"),
            metric("approximation_aabb", found.approx_err, tolerances["collision.approximation_aabb"], "relative"),
        ]
        return judged("collision", metrics, notes, settings={"geoms": model.ngeom, "shapes_checked": checked})


def _check_geom(result, model: mujoco.MjModel, data: mujoco.MjData, g: int, groups: _Groups, found: _Findings) -> None:
    """One geom against the shape PhysX holds for it: its presence, collision groups, shape class and geometry."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom#{g}"
    component, shape = sapien_side.geom_component(result, g)
    if shape is None:
        if groups.needs_shape(model, g):
            found.mismatches.append(f"{name}: colliding geom has no collision shape")
        return
    found.checked += 1
    kind = _G(int(model.geom_type[g]))
    wrong = groups.wrong(model, g, name, [int(x) for x in result.collision_groups(shape)[:2]])
    if wrong is not None:
        found.groups_wrong.append(wrong)
    pose = sapien_side.shape_world_pose(component, shape)
    if _wrong_shape_class(kind, shape):
        found.mismatches.append(f"{name}: {kind.name} became {type(shape).__name__}")
        return
    _compare_geometry(model, data, g, kind, component, shape, pose, name, found)


def _wrong_shape_class(kind: mujoco.mjtGeom, shape) -> bool:
    """The shape is not of the PhysX class that holds this geom type exactly."""
    exact = EXACT.get(kind)
    if exact is None or isinstance(shape, exact):
        return False
    # a triangle mesh on a static body is the faithful choice
    return not (kind == _G.mjGEOM_MESH and isinstance(shape, MESHLIKE))


def _compare_geometry(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    g: int,
    kind: mujoco.mjtGeom,
    component,
    shape,
    pose: sapien.Pose,
    name: str,
    found: _Findings,
) -> None:
    """A shape's size, world pose, or (meshes and hulls) world AABB against the geom's, per shape class."""
    p, rot = np.asarray(pose.p, dtype=float), _rotation(pose.q)
    ref_p, ref_rot = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
    size = model.geom_size[g]
    if kind == _G.mjGEOM_PLANE:
        normal_ref = ref_rot[:, 2]
        found.rot_err.append(line_angle(rot[:, 0], normal_ref))
        found.pos_err.append(abs(np.dot(p - ref_p, normal_ref)))
    elif kind == _G.mjGEOM_SPHERE:
        found.size_err.append(abs(shape.radius - size[0]))
        found.pos_err.append(np.linalg.norm(p - ref_p))
    elif kind in (_G.mjGEOM_CAPSULE, _G.mjGEOM_CYLINDER):
        found.size_err += [abs(shape.radius - size[0]), abs(shape.half_length - size[1])]
        found.pos_err.append(np.linalg.norm(p - ref_p))
        found.rot_err.append(line_angle(rot[:, 0], ref_rot[:, 2]))
    elif kind == _G.mjGEOM_BOX:
        found.size_err.append(np.max(np.abs(np.asarray(shape.half_size) - size)))
        found.pos_err.append(np.linalg.norm(p - ref_p))
        found.rot_err.append(float(quaternion_angle(np.asarray(pose.q, dtype=float), _mat_quat(ref_rot))))
    elif isinstance(shape, MESHLIKE):
        lo, hi = geom_world_aabb(model, data, g)
        verts = shape_world_vertices(component, shape)
        err = max(np.max(np.abs(verts.min(axis=0) - lo)), np.max(np.abs(verts.max(axis=0) - hi)))
        if kind in (_G.mjGEOM_MESH, _G.mjGEOM_HFIELD):
            found.mesh_err.append(err)
        else:  # a primitive PhysX lacks (ellipsoid, ...) approximated by a hull: relative to its size
            found.approx_err.append(err / max(float(np.max(size[:3])), 1e-9))
    else:
        found.notes.append(f"{name}: {kind.name} as {type(shape).__name__} is not compared")


def _mat_quat(rot: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, rot.ravel())
    return q
