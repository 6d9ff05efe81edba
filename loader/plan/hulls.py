"""Collision meshes cooked once per vertex set.

PhysX cooks a convex hull (or a triangle mesh) from the vertices every time SAPIEN makes a shape from vertices, and
SAPIEN 3.0.3 makes such a shape only from vertices or from a file: no shape from another shape's cooked mesh. From
a file, though, it cooks once and keeps the mesh for every later shape of that file. So a vertex set met a second
time (a mesh several geoms share, or one a later load in this process meets again) is written once to a file of
this process, and its shapes come from that file: cooked on first use, shared after, like MuJoCo's own mesh cache.
A vertex set met once is cooked from memory (a file's first use costs about half as much again).

A hull's file is binary STL: the same float32 vertices in the same order (its triangles are consecutive vertices,
the last one padded with the last vertex, a duplicate PhysX drops before it builds the hull); a triangle mesh's
(a height field's) is binary PLY with the same vertices and triangles, each vertex led by a byte SAPIEN's reader
skips (it takes whitespace bytes right after the header for padding). Either way the mesh is the one PhysX cooks
from memory, vertex for vertex (tests/test_loader_structure.py::test_a_shared_mesh_is_cooked_once).
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Iterable

import numpy as np
import sapien

_STL_HEADER = bytes(80)  # a binary STL's header: anything but a leading "solid" (which would mean ASCII)
_FACET = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
_PLY_VERTEX = np.dtype([("lead", "u1"), ("xyz", "<f4", 3)])
_PLY_FACE = np.dtype([("count", "u1"), ("corners", "<i4", 3)])

_seen: set[str] = set()  # vertex sets cooked from memory in this process
_files: dict[str, str] = {}  # vertex set -> its file (SAPIEN keeps the hull it cooked from it)
_folder: list[str] = []  # this process's folder of hull files, made on first use and removed at exit


def key(vertices: np.ndarray) -> str:
    """A vertex set's identity: the digest of its float32 coordinates in order."""
    data = np.ascontiguousarray(vertices, np.float32)
    return f"{len(data)}-{hashlib.sha256(memoryview(data).cast('B')).hexdigest()}"


def plan_sharing(plans: Iterable) -> None:
    """Mark the convex shape plans of one load whose vertex set another of them has too (`shared`), each with its
    vertex set's `mesh_key`."""
    convex = [plan for plan in plans if plan.kind == "convex"]
    keys: dict[int, str] = {}  # by vertex array: geoms of one mesh share theirs (`geom.plan_shape`)
    for plan in convex:
        plan.mesh_key = keys.get(id(plan.vertices)) or keys.setdefault(id(plan.vertices), key(plan.vertices))
    uses = Counter(plan.mesh_key for plan in convex)
    for plan in convex:
        plan.shared = uses[plan.mesh_key] > 1


def convex_shape(
    vertices: np.ndarray,
    scale: np.ndarray,
    material: sapien.physx.PhysxMaterial,
    mesh_key: str | None = None,
    shared: bool = False,
) -> sapien.physx.PhysxCollisionShapeConvexMesh:
    """A convex shape of `vertices` (float32, in the shape's frame) at `scale`: from its file where the vertex set
    is `shared` in this load or met before in this process, else cooked from memory."""
    vertices = np.ascontiguousarray(vertices, np.float32)
    scale = np.asarray(scale, np.float32)
    mesh_key = mesh_key or key(vertices)
    if shared or mesh_key in _seen or mesh_key in _files:
        return sapien.physx.PhysxCollisionShapeConvexMesh(_file(mesh_key, vertices, None), scale, material)
    shape = sapien.physx.PhysxCollisionShapeConvexMesh(vertices, scale, material)
    _seen.add(mesh_key)
    return shape


def triangle_shape(
    vertices: np.ndarray, triangles: np.ndarray, scale: np.ndarray, material: sapien.physx.PhysxMaterial
) -> sapien.physx.PhysxCollisionShapeTriangleMesh:
    """A triangle mesh shape without an SDF (a static one): from its file where met before in this process, else
    cooked from memory."""
    vertices = np.ascontiguousarray(vertices, np.float32)
    triangles = np.ascontiguousarray(triangles, np.uint32)
    scale = np.asarray(scale, np.float32)
    mesh_key = f"{key(vertices)}-{key(triangles.view(np.float32))}"
    if mesh_key in _seen or mesh_key in _files:
        return sapien.physx.PhysxCollisionShapeTriangleMesh(_file(mesh_key, vertices, triangles), scale, material)
    shape = sapien.physx.PhysxCollisionShapeTriangleMesh(vertices, triangles, scale, material)
    _seen.add(mesh_key)
    return shape


def _file(mesh_key: str, vertices: np.ndarray, triangles: np.ndarray | None) -> str:
    """The mesh's file (a hull's without `triangles`), written where it is not there yet (SAPIEN looks a file up by
    its path, and needs it present even for a mesh it keeps)."""
    path = _files.get(mesh_key)
    if path is not None and os.path.isfile(path):
        return path
    path = os.path.join(_hull_folder(), f"{mesh_key}.{'stl' if triangles is None else 'ply'}")
    partial = f"{path}.{os.getpid()}.part"
    with open(partial, "wb") as out:
        out.write(_stl(vertices) if triangles is None else _ply(vertices, triangles))
    os.replace(partial, path)
    _files[mesh_key] = path
    return path


def _stl(vertices: np.ndarray) -> bytes:
    padded = np.concatenate([vertices, np.repeat(vertices[-1:], -len(vertices) % 3, axis=0)])
    facets = np.zeros(len(padded) // 3, _FACET)
    facets["corners"] = padded.reshape(-1, 3, 3)
    return _STL_HEADER + np.uint32(len(facets)).astype("<u4").tobytes() + facets.tobytes()


def _ply(vertices: np.ndarray, triangles: np.ndarray) -> bytes:
    points = np.zeros(len(vertices), _PLY_VERTEX)
    points["lead"], points["xyz"] = 1, vertices
    faces = np.zeros(len(triangles), _PLY_FACE)
    faces["count"], faces["corners"] = 3, triangles
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\nproperty uchar lead\n"
        f"property float x\nproperty float y\nproperty float z\nelement face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    return header.encode() + points.tobytes() + faces.tobytes()


def _hull_folder() -> str:
    if not _folder or not os.path.isdir(_folder[0]):
        folder = tempfile.mkdtemp(prefix="mjcf-loader-hulls-")
        _folder[:] = [folder]
        atexit.register(_remove, folder, os.getpid())
    return _folder[0]


def _remove(folder: str, owner: int) -> None:
    if os.getpid() == owner:  # not from a forked child, whose parent still reads the files
        shutil.rmtree(folder, ignore_errors=True)
