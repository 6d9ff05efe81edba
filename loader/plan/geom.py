"""MuJoCo geoms onto PhysX collision shapes.

Sizes and poses come from the compiled model. Mesh geoms use the compiled (re-centred) vertices with the
compiled geom pose, so the hull PhysX builds sits where MuJoCo's does. Geoms with contype = conaffinity = 0
never collide in MuJoCo and get no shape.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import mujoco
import numpy as np
import sapien

from ..errors import Notes
from ..model import mj
from ..model.frames import X_TO_Z, pose

G = mujoco.mjtGeom
PLANE, HFIELD, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH = (
    int(G.mjGEOM_PLANE),
    int(G.mjGEOM_HFIELD),
    int(G.mjGEOM_SPHERE),
    int(G.mjGEOM_CAPSULE),
    int(G.mjGEOM_ELLIPSOID),
    int(G.mjGEOM_CYLINDER),
    int(G.mjGEOM_BOX),
    int(G.mjGEOM_MESH),
)
GEOM_TYPE_NAMES = {
    int(v): k.removeprefix("mjGEOM_").lower() for k, v in G.__members__.items() if int(v) < int(G.mjNGEOMTYPES)
}
# PhysX cooks convex hulls with at most this many vertices (it simplifies larger ones)
PHYSX_HULL_VERTEX_LIMIT = 255


@dataclass
class ShapePlan:
    """One collision shape: `kind` is the PhysX shape, `pose` is in the body's frame."""

    geom: int
    kind: str  # "sphere", "box", "capsule", "cylinder", "plane", "convex", "triangles"
    pose: sapien.Pose
    size: np.ndarray = field(
        default_factory=lambda: np.zeros(3)
    )  # sphere r; box half sizes; capsule/cylinder r, half length
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    friction: float = 1.0
    rest_offset: float = 0.0  # m: MuJoCo's margin - gap, where PhysX's contact comes to rest (`contact_distances`)
    torsion: float = 0.0  # m: PhysX's minimum torsional patch radius, MuJoCo's torsional friction over sliding
    groups: list[int] = field(default_factory=lambda: [0, 0, 0, 0])
    mesh_key: str | None = None  # a convex shape's vertex set (`hulls.plan_sharing`)
    shared: bool = False  # ... which another shape of the load has too: cooked once for both


def collides(model: mujoco.MjModel, g: int) -> bool:
    """Whether MuJoCo may make a contact with the geom: its bits, or an explicit `<pair>` naming it."""
    return bool(model.geom_contype[g] or model.geom_conaffinity[g]) or bool(
        model.npair and (np.any(model.pair_geom1 == g) or np.any(model.pair_geom2 == g))
    )


@lru_cache(maxsize=4)
def unit_sphere_points(n: int = 7) -> np.ndarray:
    """4 n^2 + 2 points on the unit sphere (an octahedron cut n times per edge) for ellipsoid hulls."""
    points = []
    for i in range(n + 1):
        for j in range(n + 1 - i):
            k = n - i - j
            v = np.array([i, j, k], dtype=np.float64)
            for signs in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3):
                points.append(v * signs)
    # each point once, rows in lexicographic order; a set of tuples rather than np.unique(axis=0), whose first call
    # imports numpy.ma, a cold load's largest single cost on a model with an ellipsoid
    points = np.array(sorted({tuple(p) for p in np.array(points).tolist()}))
    return (points / np.linalg.norm(points, axis=1, keepdims=True)).astype(np.float32)


def mesh_vertices(model: mujoco.MjModel, mesh: int) -> np.ndarray:
    start = model.mesh_vertadr[mesh]
    return model.mesh_vert[start : start + model.mesh_vertnum[mesh]].astype(np.float32)


def mesh_faces(model: mujoco.MjModel, mesh: int) -> np.ndarray:
    start = model.mesh_faceadr[mesh]
    return model.mesh_face[start : start + model.mesh_facenum[mesh]].astype(np.uint32)


def hfield_triangles(model: mujoco.MjModel, h: int) -> tuple[np.ndarray, np.ndarray]:
    """The top surface of a height field as a triangle mesh in the geom's frame."""
    nrow, ncol = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
    rx, ry, top, _base = model.hfield_size[h]
    start = model.hfield_adr[h]
    heights = model.hfield_data[start : start + nrow * ncol].reshape(nrow, ncol)
    x = np.linspace(-rx, rx, ncol)
    y = np.linspace(-ry, ry, nrow)
    xx, yy = np.meshgrid(x, y)
    vertices = np.stack([xx, yy, heights * top], axis=-1).reshape(-1, 3).astype(np.float32)
    index = np.arange(nrow * ncol).reshape(nrow, ncol)
    a, b, c, d = index[:-1, :-1], index[:-1, 1:], index[1:, :-1], index[1:, 1:]
    triangles = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)]).astype(
        np.uint32
    )
    return vertices, triangles


def _hull_vertices(model: mujoco.MjModel, g: int, notes: Notes, meshes: dict[int, np.ndarray] | None) -> np.ndarray:
    """A mesh geom's vertices (PhysX cooks their convex hull), kept in `meshes` for the next geom of the same mesh;
    a hull of more vertices than PhysX keeps is noted."""
    mesh = int(model.geom_dataid[g])
    vertices = meshes.get(mesh) if meshes is not None else None
    if vertices is None:
        vertices = mesh_vertices(model, mesh)
        if meshes is not None:
            meshes[mesh] = vertices
    if len(vertices) > PHYSX_HULL_VERTEX_LIMIT:
        hull = model.mesh_graph[model.mesh_graphadr[mesh]] if model.mesh_graphadr[mesh] >= 0 else 0
        if hull > PHYSX_HULL_VERTEX_LIMIT:
            notes.approximate(
                "geom",
                mj.name(model, "geom", g),
                f"convex hull of {hull} vertices simplified by PhysX to {PHYSX_HULL_VERTEX_LIMIT}",
            )
    return vertices


def plan_shape(
    model: mujoco.MjModel, g: int, static: bool, notes: Notes, meshes: dict[int, np.ndarray] | None = None
) -> ShapePlan | None:
    """The collision shape of geom `g` (None when it gets none) with its contact distances; `static` says the body
    never moves. `meshes` keeps each mesh's vertices for the geoms after the first that use it (one array, read
    only)."""
    shape = _primitive(model, g, static, notes, meshes)
    if shape is not None:
        shape.rest_offset, shape.torsion = contact_distances(model, g)
    return shape


def contact_distances(model: mujoco.MjModel, g: int) -> tuple[float, float]:
    """PhysX's rest offset and minimum torsional patch radius for geom `g`: `margin - gap`, the distance off the
    surface from which MuJoCo's contact acts (PhysX rests a pair at the sum of its shapes' rest offsets, MuJoCo at
    the larger margin less the larger gap); and, with condim 4 or more, torsional over sliding friction (PhysX's
    torsional torque is the pair's average friction times its larger patch radius times the normal force, MuJoCo's
    the larger torsional friction times the normal force). Exact where one of the two geoms carries the distance and
    the frictions agree; `contact.note_contact_distances` names the pairs where not (docs/mapping.md#geoms)."""
    rest = float(model.geom_margin[g] - model.geom_gap[g])
    sliding, torsional = float(model.geom_friction[g][0]), float(model.geom_friction[g][1])
    torsion = torsional / sliding if int(model.geom_condim[g]) >= 4 and sliding > 0 else 0.0
    return rest, torsion


def _primitive(
    model: mujoco.MjModel, g: int, static: bool, notes: Notes, meshes: dict[int, np.ndarray] | None
) -> ShapePlan | None:
    """The PhysX shape of geom `g` and its sliding friction (`plan_shape`)."""
    gtype = int(model.geom_type[g])
    size = model.geom_size[g]
    geom_pose = pose(model.geom_pos[g], model.geom_quat[g])
    friction = float(model.geom_friction[g][0])
    name = mj.name(model, "geom", g)
    if gtype == SPHERE:
        return ShapePlan(g, "sphere", geom_pose, np.array([size[0], 0, 0]), friction=friction)
    if gtype == BOX:
        return ShapePlan(g, "box", geom_pose, size.copy(), friction=friction)
    if gtype in (CAPSULE, CYLINDER):
        kind = "capsule" if gtype == CAPSULE else "cylinder"
        if gtype == CYLINDER:
            notes.approximate("geom", name, "cylinder is a convex approximation in PhysX (volume 0.64 % low)")
        return ShapePlan(
            g, kind, geom_pose * pose((0, 0, 0), X_TO_Z), np.array([size[0], size[1], 0]), friction=friction
        )
    if gtype == PLANE:
        if not static:
            notes.drop("geom", name, "plane on a moving body: PhysX planes are static only")
            return None
        return ShapePlan(g, "plane", geom_pose * pose((0, 0, 0), X_TO_Z), friction=friction)
    if gtype == ELLIPSOID:
        notes.approximate("geom", name, "ellipsoid approximated by the convex hull of 198 surface points")
        return ShapePlan(
            g, "convex", geom_pose, size.copy(), vertices=unit_sphere_points(), scale=size.copy(), friction=friction
        )
    if gtype == MESH:
        return ShapePlan(g, "convex", geom_pose, vertices=_hull_vertices(model, g, notes, meshes), friction=friction)
    if gtype == HFIELD:
        if not static:
            notes.drop("geom", name, "height field on a moving body is not supported")
            return None
        vertices, triangles = hfield_triangles(model, int(model.geom_dataid[g]))
        return ShapePlan(g, "triangles", geom_pose, vertices=vertices, triangles=triangles, friction=friction)
    notes.drop("geom", name, f"geom type '{GEOM_TYPE_NAMES.get(gtype, gtype)}' has no PhysX shape")
    return None
