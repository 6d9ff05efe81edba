"""Both sides' shapes in the 3D view: MuJoCo's solid and lit in grey, SAPIEN's collision shapes as orange outlines
over them, so surfaces that coincide (the conforming case) never z-fight and a gap between them shows as lines
off the surface (`test_rerun_recording.py::test_sapien_is_drawn_as_outlines_over_mujocos_surfaces`).

MuJoCo draws its collision geoms (contype or conaffinity set); visual-only meshes are drawn on request, in their
authored colours. Planes are drawn only when the motion shown has contacts on, and at a size fitted to the robot's
bounding box, not MuJoCo's infinite or rendering size
(`test_rerun_recording.py::test_the_failing_contact_rollout_plays_with_the_floor`)."""

from __future__ import annotations

import mujoco
import numpy as np
import rerun as rr
import sapien

from .. import sapien_side
from . import meshes
from .paths import body_path, link_path, part
from .poses import Motion, compose, geom_local, geom_world, rotate, xyzw
from .timeline import times

MUJOCO_COLOR = [150, 170, 200, 255]
SAPIEN_COLOR = [255, 140, 0, 255]
OUTLINE = "majorwireframe"
_Z_TO_X = np.array([0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])  # xyzw: +90 deg about y maps +Z to +X
_THIN = 1e-3  # half thickness of a drawn plane (m)
PLANE_MARGIN = 0.5  # a plane reaches this fraction of the robot's largest extent beyond it on each side


def drawn(model: mujoco.MjModel, g: int, visual: bool) -> bool:
    return visual or bool(model.geom_contype[g] or model.geom_conaffinity[g])


def _robot_geoms(model: mujoco.MjModel) -> list[int]:
    """The geoms on bodies (the world's terrain and walls are scenery), else every geom but planes."""
    solid = [g for g in range(model.ngeom) if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE]
    return [g for g in solid if model.geom_bodyid[g] != 0] or solid


def bounding_box(model: mujoco.MjModel, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The box the robot's geoms' bounding spheres stay in along the motion (`_robot_geoms`, else the bodies)."""
    geoms = _robot_geoms(model)
    if geoms:
        centers = np.stack([geom_world(model, motion, g)[:, :3] for g in geoms], axis=1)  # (T, G, 3)
        radius = model.geom_rbound[geoms][None, :, None]
        lo, hi = np.nanmin(centers - radius, axis=(0, 1)), np.nanmax(centers + radius, axis=(0, 1))
    else:
        points = motion.mujoco_body_pose[:, :, :3].reshape(-1, 3)
        lo, hi = np.nanmin(points, axis=0), np.nanmax(points, axis=0)
    return lo, hi


_SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def start_box(model: mujoco.MjModel, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The box around the robot (`_robot_geoms`, else the bodies' origins) at the motion's first sample, the pose
    the 3D view opens on: the corners of each geom's own box (MuJoCo's `geom_aabb`, in the geom's frame) in the
    world. Tighter than `bounding_box`'s spheres, so that the camera frames the robot, not the room around it."""
    geoms = _robot_geoms(model)
    if not geoms:
        points = motion.mujoco_body_pose[0, :, :3]
    else:
        aabb = model.geom_aabb[geoms]  # (G, 6): center, half sizes
        local = aabb[:, None, :3] + aabb[:, None, 3:] * _SIGNS  # (G, 8, 3)
        frames = np.concatenate([model.geom_pos[geoms], model.geom_quat[geoms]], axis=1)  # in their bodies
        poses = compose(motion.mujoco_body_pose[0, model.geom_bodyid[geoms]], frames)  # (G, 7) in the world
        points = (poses[:, None, :3] + rotate(poses[:, None, 3:], local)).reshape(-1, 3)
    return np.nanmin(points, axis=0), np.nanmax(points, axis=0)


def fitted_rectangle(world: np.ndarray, axes: tuple[int, int], limit: np.ndarray, box) -> tuple[np.ndarray, np.ndarray]:
    """(center, half) of a plane's drawn rectangle in its own frame, over the in-plane `axes`: the robot's box
    projected onto the plane plus a margin, inside the plane's own `limit` half sizes where they are finite (> 0)."""
    lo, hi = box
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    conj = world[3:] * np.array([1.0, -1.0, -1.0, -1.0])
    local = rotate(conj, corners - world[:3])[:, list(axes)]
    a, b = local.min(axis=0), local.max(axis=0)
    pad = PLANE_MARGIN * max(float(np.max(b - a)), 1e-2)
    a, b = a - pad, b + pad
    finite = np.asarray(limit, dtype=float) > 0
    a = np.where(finite, np.maximum(a, -limit), a)
    b = np.where(finite, np.minimum(b, limit), b)
    b = np.where(b > a, b, a + 2 * np.where(finite, limit, pad))
    return (a + b) / 2, (b - a) / 2


def _static_pose(rec: rr.RecordingStream, path: str, pose7: np.ndarray) -> None:
    rec.log(path, rr.Transform3D(translation=pose7[:3], quaternion=xyzw(pose7[3:])), static=True)


def _mujoco_primitive(model: mujoco.MjModel, g: int):
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    G = mujoco.mjtGeom
    color = [MUJOCO_COLOR]
    if kind == G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size[:3]], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size[:3]], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_CAPSULE:
        return rr.Capsules3D(
            lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=color, fill_mode="solid"
        )
    if kind == G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=color, fill_mode="solid")
    return None  # meshes are instanced, planes fitted; height fields and SDFs are not drawn


def authored_color(model: mujoco.MjModel, g: int) -> list[int]:
    """A geom's colour as MuJoCo renders it (its material's, else its own), opaque: a visual mesh looks as
    authored, apart from the grey collision geometry."""
    rgba = model.mat_rgba[model.geom_matid[g]] if model.geom_matid[g] >= 0 else model.geom_rgba[g]
    return [*(int(255 * c + 0.5) for c in np.clip(rgba[:3], 0, 1)), 255]


def geom_path(model: mujoco.MjModel, g: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
    return f"{body_path(model, int(model.geom_bodyid[g]))}/geom/{part(name)}"


def mesh_path(model: mujoco.MjModel, m: int, hull: bool) -> str:
    """`mujoco/hull/<mesh>` for the convex hull MuJoCo collides with, `mujoco/mesh/<mesh>` for the mesh itself."""
    name = part(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, m) or f"mesh{m}")
    return f"mujoco/{'hull' if hull else 'mesh'}/{name}"


def log_mujoco(rec: rr.RecordingStream, model: mujoco.MjModel, motion: Motion, box, visual: bool) -> set[int]:
    """Primitives in their body frames, each distinct mesh (or hull) once with its instances' world poses per step.
    Returns the bodies that carry a primitive (the others need no frame)."""
    users: dict[tuple[int, bool], list[int]] = {}
    framed: set[int] = set()
    for g in range(model.ngeom):
        if not drawn(model, g, visual):
            continue
        kind = int(model.geom_type[g])
        if kind == mujoco.mjtGeom.mjGEOM_MESH:
            m = int(model.geom_dataid[g])
            colliding = bool(model.geom_contype[g] or model.geom_conaffinity[g]) and model.mesh_graphadr[m] >= 0
            users.setdefault((m, colliding), []).append(g)
        elif kind == mujoco.mjtGeom.mjGEOM_PLANE:
            if motion.contact:
                world = geom_world(model, motion, g)[0]
                center, half = fitted_rectangle(world, (0, 1), model.geom_size[g][:2], box)
                _static_pose(rec, geom_path(model, g), geom_local(model, g))
                rec.log(
                    geom_path(model, g),
                    rr.Boxes3D(
                        half_sizes=[[*half, _THIN]],
                        centers=[[*center, -_THIN]],
                        colors=[MUJOCO_COLOR],
                        fill_mode="solid",
                    ),
                    static=True,
                )
        elif (shape := _mujoco_primitive(model, g)) is not None:
            _static_pose(rec, geom_path(model, g), geom_local(model, g))
            rec.log(geom_path(model, g), shape, static=True)
            framed.add(int(model.geom_bodyid[g]))
    for (m, colliding), geoms in users.items():
        path = mesh_path(model, m, colliding)
        vertices, faces = meshes.hull(model, m) if colliding else meshes.surface(model, m)
        color = MUJOCO_COLOR if colliding else authored_color(model, geoms[0])
        rec.log(path, meshes.mesh(vertices, faces, color), static=True)
        poses = np.stack([geom_world(model, motion, g) for g in geoms], axis=1)  # (T, k, 7)
        if motion.time is None:
            rec.log(
                path, rr.InstancePoses3D(translations=poses[0, :, :3], quaternions=xyzw(poses[0, :, 3:])), static=True
            )
        else:
            rec.send_columns(path, indexes=times(motion.time), columns=meshes.instance_columns(poses))
    return framed


def _sapien_shape(shape, plane_world: np.ndarray | None, box):
    P = sapien.physx
    color = [SAPIEN_COLOR]
    if isinstance(shape, P.PhysxCollisionShapeSphere):
        return rr.Ellipsoids3D(half_sizes=[[shape.radius] * 3], colors=color, fill_mode=OUTLINE)
    if isinstance(shape, P.PhysxCollisionShapeBox):
        return rr.Boxes3D(half_sizes=[shape.half_size], colors=color, fill_mode=OUTLINE)
    if isinstance(shape, P.PhysxCollisionShapeCapsule):  # SAPIEN's axis is +X
        return rr.Capsules3D(
            lengths=[2 * shape.half_length],
            radii=[shape.radius],
            translations=[[-shape.half_length, 0, 0]],
            quaternions=[_Z_TO_X],
            colors=color,
            fill_mode=OUTLINE,
        )
    if isinstance(shape, P.PhysxCollisionShapeCylinder):
        return rr.Cylinders3D(
            lengths=[2 * shape.half_length],
            radii=[shape.radius],
            quaternions=[_Z_TO_X],
            colors=color,
            fill_mode=OUTLINE,
        )
    if isinstance(shape, P.PhysxCollisionShapePlane):  # SAPIEN's normal is +X
        if plane_world is None:
            return None
        center, half = fitted_rectangle(plane_world, (1, 2), np.zeros(2), box)
        return rr.Boxes3D(half_sizes=[[_THIN, *half]], centers=[[-_THIN, *center]], colors=color, fill_mode=OUTLINE)
    if isinstance(shape, (P.PhysxCollisionShapeConvexMesh, P.PhysxCollisionShapeTriangleMesh)):
        verts = np.asarray(shape.get_vertices(), dtype=float) * np.asarray(shape.get_scale(), dtype=float)
        return meshes.outline(verts, np.asarray(shape.get_triangles()), color)
    return None


def log_sapien(rec: rr.RecordingStream, result, motion: Motion, box) -> set[int]:
    """The shapes PhysX holds, read back from the components: in link frames, static actors' in the world.
    Returns the rows (`sapien_side.links`) of the links that carry a shape."""
    framed: set[int] = set()
    for row, (a, link) in enumerate(sapien_side.links(result)):
        for k, shape in enumerate(link.collision_shapes):
            drawn_shape = _sapien_shape(shape, None, box)  # PhysX holds planes on static actors only
            if drawn_shape is not None:
                path = f"{link_path(a, link)}/shape/{k}"
                _static_pose(rec, path, sapien_side.pose7(shape.local_pose))
                rec.log(path, drawn_shape, static=True)
                framed.add(row)
    for i, actor in enumerate(result.actors):
        component = sapien_side.rigid_component(actor)
        for k, shape in enumerate(component.collision_shapes):
            pose = sapien_side.pose7(sapien_side.shape_world_pose(component, shape))
            drawn_shape = _sapien_shape(shape, pose if motion.contact else None, box)
            if drawn_shape is not None:
                path = f"sapien/static/{part(actor.name or str(i))}/shape/{k}"
                _static_pose(rec, path, pose)
                rec.log(path, drawn_shape, static=True)
    return framed
