"""Every corpus model: DoF count, link poses, inertia and collision shapes against MuJoCo's compiled model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import sapien
from models import corpus_params
from reference import body_poses, random_qpos, rotation_angle, touching_geom_pairs

from loader.frames import X_TO_Z, quat_mul

POSE_TOLERANCE = 1e-5  # m and rad: SAPIEN poses are float32 (about 1e-7 relative); measured worst 1.6e-6
INERTIA_RTOL = 1e-6
CORPUS = corpus_params()


def _link(result, body):
    target = result.mapping.bodies[body]
    return result.articulations[target.articulation].links[target.link]


@pytest.mark.parametrize("path", CORPUS)
def test_dof_count_equals_mujoco_nv(load, path):
    result = load(path)
    model = result.model
    floating = sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    assert sum(art.dof for art in result.articulations) + 6 * floating == model.nv
    assert sum(1 for art in result.articulations if not art.root.joint.type == "fixed") >= floating


@pytest.mark.parametrize("path", CORPUS)
def test_link_poses_match_mujoco_bodies(load, path, rng):
    result = load(path)
    model = result.model
    worst = 0.0
    for trial in range(21):
        qpos = model.qpos0.copy() if trial == 0 else random_qpos(model, rng)
        result.mapping.set_state(result.articulations, qpos)
        xpos, xquat = body_poses(model, qpos)
        for body in range(1, model.nbody):
            link_pose = _link(result, body).entity_pose
            assert np.abs(link_pose.p - xpos[body]).max() < POSE_TOLERANCE, (model.body(body).name, trial)
            angle = rotation_angle(xquat[body], link_pose.q)
            assert angle < POSE_TOLERANCE, (model.body(body).name, trial, angle)
            worst = max(worst, angle)
    result.reset()


@pytest.mark.parametrize("path", CORPUS)
def test_mass_centre_and_inertia_tensor_match(load, path):
    result = load(path)
    model = result.model
    for body in range(1, model.nbody):
        link = _link(result, body)
        mass = model.body_mass[body]
        if mass == 0:
            assert link.mass < 1e-6  # a massless MuJoCo body gets only PhysX's positive floor
            continue
        np.testing.assert_allclose(link.mass, mass, rtol=INERTIA_RTOL)
        cmass = link.cmass_local_pose
        np.testing.assert_allclose(cmass.p, model.body_ipos[body], rtol=INERTIA_RTOL, atol=1e-7)
        # full tensors in the body frame: R diag(I) R^T on both sides
        r_sapien = sapien.Pose(q=cmass.q).to_transformation_matrix()[:3, :3]
        r_mujoco = np.zeros(9)
        mujoco.mju_quat2Mat(r_mujoco, model.body_iquat[body])
        r_mujoco = r_mujoco.reshape(3, 3)
        tensor_sapien = r_sapien @ np.diag(link.inertia) @ r_sapien.T
        tensor_mujoco = r_mujoco @ np.diag(model.body_inertia[body]) @ r_mujoco.T
        scale = np.abs(tensor_mujoco).max()
        assert np.abs(tensor_sapien - tensor_mujoco).max() <= 1e-6 * scale + 1e-9, model.body(body).name


def _shape_size(shape):
    if isinstance(shape, sapien.physx.PhysxCollisionShapeSphere):
        return "sphere", np.array([shape.radius])
    if isinstance(shape, sapien.physx.PhysxCollisionShapeBox):
        return "box", np.asarray(shape.half_size)
    if isinstance(shape, sapien.physx.PhysxCollisionShapeCapsule):
        return "capsule", np.array([shape.radius, shape.half_length])
    if isinstance(shape, sapien.physx.PhysxCollisionShapeCylinder):
        return "cylinder", np.array([shape.radius, shape.half_length])
    if isinstance(shape, sapien.physx.PhysxCollisionShapePlane):
        return "plane", np.zeros(0)
    if isinstance(shape, sapien.physx.PhysxCollisionShapeConvexMesh):
        return "convex", None
    return "triangles", None


EXPECTED_KIND = {"sphere": "sphere", "box": "box", "capsule": "capsule", "cylinder": "cylinder", "plane": "plane",
                 "ellipsoid": "convex", "mesh": "convex", "hfield": "triangles"}


def _component(result, target):
    if target.articulation is None:
        return next(c for c in result.actors[target.actor].components if isinstance(c, sapien.physx.PhysxRigidBaseComponent))
    return result.articulations[target.articulation].links[target.link]


@pytest.mark.parametrize("path", CORPUS)
def test_collision_shapes_have_type_size_and_world_pose(load, path):
    result = load(path)
    model = result.model
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, data)
    result.reset()
    for g in range(model.ngeom):
        target = result.mapping.geoms[g]
        kind = mujoco.mjtGeom(model.geom_type[g]).name.removeprefix("mjGEOM_").lower()
        if not (model.geom_contype[g] or model.geom_conaffinity[g]):
            assert target is None
            continue
        dropped = {entry.name for entry in result.unsupported if entry.kind == "geom"}
        if target is None:
            assert (model.geom(g).name or f"geom{g}") in dropped
            continue
        component = _component(result, target)
        shape = component.collision_shapes[target.shape]
        shape_kind, size = _shape_size(shape)
        assert shape_kind == EXPECTED_KIND[kind]
        if kind in ("sphere",):
            np.testing.assert_allclose(size, model.geom_size[g][:1], rtol=1e-6)
        elif kind == "box":
            np.testing.assert_allclose(size, model.geom_size[g], rtol=1e-6)
        elif kind in ("capsule", "cylinder"):
            np.testing.assert_allclose(size, model.geom_size[g][:2], rtol=1e-6)
        world = component.entity_pose * shape.local_pose
        expected_q = data.xquat[g] if False else None
        geom_quat = np.zeros(4)
        mujoco.mju_mat2Quat(geom_quat, data.geom_xmat[g])
        if kind in ("capsule", "cylinder", "plane"):
            geom_quat = quat_mul(geom_quat, X_TO_Z)
        assert np.abs(world.p - data.geom_xpos[g]).max() < POSE_TOLERANCE
        assert rotation_angle(geom_quat, world.q) < POSE_TOLERANCE
        if kind == "mesh":  # the hull's vertices are the compiled mesh's own
            vertices = np.asarray(shape.get_vertices())
            mesh = model.geom_dataid[g]
            compiled = model.mesh_vert[model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
            distance = np.min(np.linalg.norm(vertices[:, None, :] - compiled[None, :, :], axis=2), axis=1)
            assert distance.max() < 1e-5


def _physx_would_collide(result, shape_a, comp_a, shape_b, comp_b) -> bool:
    ga, gb = shape_a.get_collision_groups(), shape_b.get_collision_groups()
    if (ga[2] & gb[2]) and (ga[3] & 0xFFFF) == (gb[3] & 0xFFFF):
        return False
    return bool((ga[0] & gb[1]) or (ga[1] & gb[0]))


@pytest.mark.parametrize("path", CORPUS)
def test_collision_filter_lets_the_same_geom_pairs_touch_as_mujoco(load, path):
    """MuJoCo is the oracle (every geom given a huge margin, so every pair its filters keep makes a contact)."""
    result = load(path)
    model = result.model
    mujoco_pairs = touching_geom_pairs(result.spec)
    allowed_gaps = {entry.name for entry in result.approximations + result.unsupported if entry.kind == "contact"}
    static_bodies = {b for b in range(model.nbody) if model.body_weldid[b] == 0}
    collision_geoms = [g for g in range(model.ngeom) if result.mapping.geoms[g] is not None]
    mismatches = []
    for i, a in enumerate(collision_geoms):
        for b in collision_geoms[i + 1 :]:
            body_a, body_b = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
            if body_a == body_b or (body_a in static_bodies and body_b in static_bodies):
                continue
            if model.geom_type[a] == model.geom_type[b] == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            ta, tb = result.mapping.geoms[a], result.mapping.geoms[b]
            comp_a, comp_b = _component(result, ta), _component(result, tb)
            physx = _physx_would_collide(result, comp_a.collision_shapes[ta.shape], comp_a,
                                         comp_b.collision_shapes[tb.shape], comp_b)
            link_a, link_b = result.mapping.bodies[body_a], result.mapping.bodies[body_b]
            if physx and link_a.articulation is not None and link_a.articulation == link_b.articulation:
                art = result.articulations[link_a.articulation]
                la, lb = art.links[link_a.link], art.links[link_b.link]
                if (la.parent is not None and la.parent.name == lb.name) or (lb.parent is not None and lb.parent.name == la.name):
                    physx = False  # PhysX never lets a link touch its direct parent
            if physx != ((a, b) in mujoco_pairs):
                names = {f"{model.body(body_a).name or f'body{body_a}'}/{model.body(body_b).name or f'body{body_b}'}",
                         f"{model.body(body_b).name or f'body{body_b}'}/{model.body(body_a).name or f'body{body_a}'}"}
                if not (names & allowed_gaps):
                    mismatches.append((model.geom(a).name or a, model.geom(b).name or b, physx))
    assert not mismatches, mismatches[:10]
