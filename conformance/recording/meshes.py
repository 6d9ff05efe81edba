"""Triangle meshes drawn once and instanced, lit by vertex normals; SAPIEN's hulls as their edges.

A MuJoCo mesh is logged once and drawn at every geom that uses it through per-step `InstancePoses3D` (world
poses), so a mesh shared by many geoms costs its vertices once
(`test_rerun_recording.py::test_each_distinct_mesh_is_logged_once_with_normals`). A colliding mesh geom is drawn as
the convex hull MuJoCo collides it with, a visual one as authored. A mesh without normals is drawn unlit, hence the
normals, creased (`test_rerun_recording.py::test_a_box_mesh_keeps_its_edges_a_curved_one_is_smooth`)."""

from __future__ import annotations

import numpy as np
import rerun as rr

from .poses import xyzw

FEATURE_ANGLE = np.deg2rad(20.0)  # hull edges between faces bent less than this are not drawn
CREASE_ANGLE = np.deg2rad(30.0)  # faces bent more than this from each other are shaded apart (a box's edges)


def creased(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices, faces, unit normals) shaded with creases: a triangle corner's normal is the area-weighted sum of
    the normals of the faces around its vertex that bend less than CREASE_ANGLE from its own face, so a curved
    surface is smooth and a box keeps its edges; corners of one vertex with one normal share a vertex."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    weighted = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # length = twice the area
    unit = weighted / np.maximum(np.linalg.norm(weighted, axis=1, keepdims=True), 1e-30)
    corner_v, corner_f = f.ravel(), np.repeat(np.arange(f.shape[0]), 3)
    order = np.argsort(corner_v, kind="stable")
    ordered = corner_v[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    counts = np.diff(np.r_[starts, ordered.size])
    normals = np.zeros((corner_v.size, 3))
    for k in np.unique(counts):  # every pair of corners at one vertex, vertices of equal degree at once
        first = starts[counts == k][:, None, None]
        ci = order[np.broadcast_to(first + np.arange(k)[None, :, None], (first.shape[0], k, k))].ravel()
        cj = order[np.broadcast_to(first + np.arange(k)[None, None, :], (first.shape[0], k, k))].ravel()
        near = np.einsum("ij,ij->i", unit[corner_f[ci]], unit[corner_f[cj]]) > np.cos(CREASE_ANGLE)
        np.add.at(normals, ci[near], weighted[corner_f[cj[near]]])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])
    key = np.column_stack([corner_v, np.round(normals * 1e4).astype(np.int64)])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return v[corner_v[first]], inverse.reshape(-1, 3), normals[first]


def hull(model, m: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, faces) of the convex hull MuJoCo collides mesh `m` with (from `mesh_graph`: numvert, numface,
    vert_edgeadr, vert_globalid, edge_localid, face_globalid), compacted to the vertices it uses; None when
    MuJoCo computed none."""
    adr = int(model.mesh_graphadr[m])
    if adr < 0:
        return None
    graph = model.mesh_graph[adr:]
    nv, nf = int(graph[0]), int(graph[1])
    start = 2 + 3 * nv + 3 * nf
    faces = graph[start : start + 3 * nf].reshape(-1, 3)
    used, faces = np.unique(faces, return_inverse=True)
    v0 = int(model.mesh_vertadr[m])
    return model.mesh_vert[v0 + used], faces.reshape(-1, 3)


def surface(model, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of mesh `m` as authored."""
    v0, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
    f0, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
    return model.mesh_vert[v0 : v0 + nv], model.mesh_face[f0 : f0 + nf]


def mesh(vertices: np.ndarray, faces: np.ndarray, color) -> rr.Mesh3D:
    v, f, n = creased(vertices, faces)
    return rr.Mesh3D(
        vertex_positions=v.astype(np.float32),
        triangle_indices=f.astype(np.uint32),
        vertex_normals=n.astype(np.float32),
        albedo_factor=color,
    )


def feature_edges(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(E, 2, 3) segments: the edges of the surface whose faces meet at more than FEATURE_ANGLE, and open edges.
    A convex hull's triangulated facets then draw as their outlines."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return np.zeros((0, 2, 3))
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    owner = np.tile(np.arange(f.shape[0]), 3)
    key = np.sort(edges, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, owner = key[order], owner[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    keep = np.ones(key.shape[0], dtype=bool)
    # a shared edge appears twice in a row: keep the first only if its two faces bend
    shared = np.flatnonzero(same)
    bend = np.einsum("ij,ij->i", n[owner[shared]], n[owner[shared + 1]]) < np.cos(FEATURE_ANGLE)
    keep[shared] = bend
    keep[shared + 1] = False
    key = key[keep]
    return np.stack([v[key[:, 0]], v[key[:, 1]]], axis=1)


def outline(vertices: np.ndarray, faces: np.ndarray, color) -> rr.LineStrips3D:
    return rr.LineStrips3D(feature_edges(vertices, faces).astype(np.float32), colors=color)


def instance_columns(poses: np.ndarray) -> rr.ComponentColumnList:
    """Per-step instance poses (T, k, 7) as columns: k instances in every row."""
    steps, k = poses.shape[:2]
    flat = poses.reshape(-1, 7)
    return rr.InstancePoses3D.columns(
        translations=flat[:, :3].astype(np.float32), quaternions=xyzw(flat[:, 3:]).astype(np.float32)
    ).partition([k] * steps)
