"""Visual shapes: geoms in the chosen groups, with their colour and mesh, where a render device exists.

Without a render device (a machine with no GPU) SAPIEN cannot build any visual shape: visuals are skipped
once, with a warning, and physics loads as usual.
"""

from __future__ import annotations

import warnings
from functools import lru_cache

import mujoco
import numpy as np
import sapien

from ..model.frames import X_TO_Z, pose
from .geom import (
    BOX,
    CAPSULE,
    CYLINDER,
    ELLIPSOID,
    MESH,
    PLANE,
    SPHERE,
    mesh_faces,
    mesh_vertices,
    unit_sphere_points,
)

DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)


class NoRenderDeviceWarning(UserWarning):
    """Visual shapes were skipped because SAPIEN found no render device."""


@lru_cache(maxsize=1)
def has_render_device() -> bool:
    try:
        sapien.render.RenderSystem()
    except RuntimeError:
        return False
    return True


_warned = False


def scene_renders(scene: sapien.Scene) -> bool:
    """The scene has a render system (a scene of sub-scenes, ManiSkill's: its first sub-scene has one)."""
    scene = getattr(scene, "sub_scenes", [scene])[0]
    try:
        scene.get_system("render")
    except RuntimeError:
        return False
    return True


def visuals_available(scene: sapien.Scene) -> bool:
    """Visual shapes can be built: a render device exists and the scene has a render system."""
    global _warned
    if has_render_device() and scene_renders(scene):
        return True
    if not _warned:
        reason = "no render device" if not has_render_device() else "the scene has no render system"
        warnings.warn(f"{reason}: visual shapes are skipped, physics is loaded", NoRenderDeviceWarning, stacklevel=3)
        _warned = True
    return False


def geom_rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    """The colour MuJoCo renders: the material's only when the geom's own rgba is the default."""
    rgba = model.geom_rgba[g].astype(np.float32)
    material = int(model.geom_matid[g])
    if material >= 0 and np.allclose(rgba, DEFAULT_RGBA):
        rgba = model.mat_rgba[material].astype(np.float32)
    return rgba


def add_visual(builder, model: mujoco.MjModel, g: int) -> None:
    """Record geom `g` as a visual shape on `builder` (call only where a render device exists)."""
    rgba = geom_rgba(model, g)
    material = sapien.render.RenderMaterial(base_color=[float(x) for x in rgba])
    gtype = int(model.geom_type[g])
    size = model.geom_size[g]
    geom_pose = pose(model.geom_pos[g], model.geom_quat[g])
    along_z = geom_pose * pose((0, 0, 0), X_TO_Z)
    name = model.geom(g).name
    if gtype == SPHERE:
        builder.add_sphere_visual(geom_pose, float(size[0]), material, name)
    elif gtype == BOX:
        builder.add_box_visual(geom_pose, size.astype(np.float32), material, name)
    elif gtype == CAPSULE:
        builder.add_capsule_visual(along_z, float(size[0]), float(size[1]), material, name)
    elif gtype == CYLINDER:
        builder.add_cylinder_visual(along_z, float(size[0]), float(size[1]), material, name)
    elif gtype == PLANE:
        extent = [1.0, size[0] or 50.0, size[1] or 50.0]
        builder.add_plane_visual(along_z, np.asarray(extent, np.float32), material, name)
    elif gtype == ELLIPSOID:
        # PhysX's hull of the scaled sphere points gives the triangles, without a GPU or another dependency
        hull = sapien.physx.PhysxCollisionShapeConvexMesh(
            unit_sphere_points() * size.astype(np.float32), np.ones(3, np.float32), sapien.physx.get_default_material()
        )
        builder.mesh_visuals.append((geom_pose, hull.get_vertices(), hull.get_triangles(), material, name))
    elif gtype == MESH:
        mesh = int(model.geom_dataid[g])
        builder.mesh_visuals.append((geom_pose, mesh_vertices(model, mesh), mesh_faces(model, mesh), material, name))


def attach_mesh_visuals(component, mesh_visuals) -> None:
    """In-memory triangle meshes (SAPIEN's builder records take file names only)."""
    for geom_pose, vertices, faces, material, name in mesh_visuals:
        normals = _vertex_normals(vertices, faces)
        uvs = np.zeros((len(vertices), 2), np.float32)
        shape = sapien.render.RenderShapeTriangleMesh(vertices, faces, normals, uvs, material)
        shape.local_pose = geom_pose
        shape.name = name
        component.attach(shape)


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    face_normals = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, faces[:, i], face_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return (normals / np.where(length > 0, length, 1)).astype(np.float32)
