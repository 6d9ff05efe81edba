"""Every corpus model: DoF count, link poses, inertia and collision shapes against MuJoCo's compiled model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import sapien
from support.corpus import corpus_params
from support.oracle import (
    POSE_TOLERANCE,
    collision_filter_mismatches,
    component_of,
    link_of,
    link_pose_errors,
)

from conformance.sampling import quaternion_angle
from loader.model.frames import X_TO_Z, quat_mul

INERTIA_RTOL = 1e-6
CORPUS = corpus_params()


@pytest.mark.parametrize("path", CORPUS)
def test_dof_count_equals_mujoco_nv(load, path):
    result = load(path)
    model = result.model
    floating = sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    assert sum(art.dof for art in result.articulations) + 6 * floating == model.nv
    assert sum(1 for art in result.articulations if art.root.joint.type != "fixed") >= floating


@pytest.mark.parametrize("path", CORPUS)
def test_link_poses_match_mujoco_bodies(load, path, rng):
    worst_position, worst_angle = link_pose_errors(load(path), rng, random_configurations=20)
    assert worst_position < POSE_TOLERANCE and worst_angle < POSE_TOLERANCE


@pytest.mark.parametrize("path", CORPUS)
def test_mass_centre_and_inertia_tensor_match(load, path):
    result = load(path)
    model = result.model
    for body in range(1, model.nbody):
        link = link_of(result, body)
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


EXPECTED_KIND = {
    "sphere": "sphere",
    "box": "box",
    "capsule": "capsule",
    "cylinder": "cylinder",
    "plane": "plane",
    "ellipsoid": "convex",
    "mesh": "convex",
    "hfield": "triangles",
}


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
        component = component_of(result, target)
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
        geom_quat = np.zeros(4)
        mujoco.mju_mat2Quat(geom_quat, data.geom_xmat[g])
        if kind in ("capsule", "cylinder", "plane"):
            geom_quat = quat_mul(geom_quat, X_TO_Z)
        assert np.abs(world.p - data.geom_xpos[g]).max() < POSE_TOLERANCE
        assert quaternion_angle(geom_quat, world.q) < POSE_TOLERANCE
        if kind == "mesh":  # the hull's vertices are the compiled mesh's own
            vertices = np.asarray(shape.get_vertices())
            mesh = model.geom_dataid[g]
            compiled = model.mesh_vert[model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
            distance = np.min(np.linalg.norm(vertices[:, None, :] - compiled[None, :, :], axis=2), axis=1)
            assert distance.max() < 1e-5


@pytest.mark.parametrize("path", CORPUS)
def test_collision_filter_lets_the_same_geom_pairs_touch_as_mujoco(load, path):
    """MuJoCo is the oracle: every geom made to overlap every other, mj_collision says which pairs it keeps."""
    assert not collision_filter_mismatches(load(path))
