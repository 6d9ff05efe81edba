"""MuJoCo as the oracle: poses, random configurations and the geom pairs MuJoCo lets touch."""

from __future__ import annotations

import mujoco
import numpy as np
import sapien

from conformance.sampling import quaternion_angle
from conformance.sampling import random_configuration as random_qpos


def body_poses(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return data.xpos.copy(), data.xquat.copy()


def touching_geom_pairs(spec: mujoco.MjSpec) -> set[tuple[int, int]]:
    """Geom pairs MuJoCo's collision pipeline keeps (its bit rule and body filters), found by turning every
    geom into a 100 m sphere at its body's origin so that every pair overlaps, then asking mj_collision."""
    spec = spec.copy()
    spec.memory = 1 << 28
    for geom in spec.geoms:
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [100.0, 0.0, 0.0]
        geom.meshname = ""
        geom.hfieldname = ""
        geom.fromto = [np.nan] * 6
        geom.pos = [0.0, 0.0, 0.0]
    probe = spec.compile()
    data = mujoco.MjData(probe)
    mujoco.mj_kinematics(probe, data)
    mujoco.mj_collision(probe, data)
    return {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in data.contact[: data.ncon]}


POSE_TOLERANCE = 1e-5  # m and rad: SAPIEN poses are float32 (about 1e-7 relative); corpus worst 1.6e-6


def link_of(result, body: int):
    target = result.mapping.bodies[body]
    return result.articulations[target.articulation].links[target.link]


def component_of(result, target):
    """The link or static-actor component that carries a geom's shape."""
    if target.articulation is None:
        return next(
            c for c in result.actors[target.actor].components if isinstance(c, sapien.physx.PhysxRigidBaseComponent)
        )
    return result.articulations[target.articulation].links[target.link]


def link_pose_errors(result, rng: np.random.Generator, random_configurations: int) -> tuple[float, float]:
    """Worst position (m) and angle (rad) between SAPIEN links and MuJoCo bodies, at qpos0 and random states."""
    model = result.model
    worst_position = worst_angle = 0.0
    for trial in range(random_configurations + 1):
        qpos = model.qpos0.copy() if trial == 0 else random_qpos(model, rng)
        result.mapping.set_state(result.articulations, qpos)
        xpos, xquat = body_poses(model, qpos)
        for body in range(1, model.nbody):
            link_pose = link_of(result, body).entity_pose
            worst_position = max(worst_position, float(np.abs(link_pose.p - xpos[body]).max()))
            worst_angle = max(worst_angle, float(quaternion_angle(xquat[body], link_pose.q)))
    result.reset()
    return worst_position, worst_angle


def _physx_collides(result, shape_a, shape_b) -> bool:
    """PhysX's group rule as SAPIEN's filter applies it (docs/mapping.md#collision-filter), to the model's own
    words (`LoadResult.collision_groups`)."""
    ga, gb = result.collision_groups(shape_a), result.collision_groups(shape_b)
    if (ga[2] & gb[2]) and (ga[3] & 0xFFFF) == (gb[3] & 0xFFFF):
        return False
    return bool((ga[0] & gb[1]) or (ga[1] & gb[0]))


def _direct_parent_child(result, body_a: int, body_b: int) -> bool:
    link_a, link_b = result.mapping.bodies[body_a], result.mapping.bodies[body_b]
    if link_a.articulation is None or link_a.articulation != link_b.articulation:
        return False
    la, lb = link_of(result, body_a), link_of(result, body_b)
    return (la.parent is not None and la.parent.name == lb.name) or (
        lb.parent is not None and lb.parent.name == la.name
    )


def collision_filter_mismatches(result) -> list[tuple]:
    """Geom pairs where PhysX's decision (groups, and its parent/child rule) differs from MuJoCo's, leaving out
    the pairs the loader reported as contact approximations."""
    model = result.model
    mujoco_pairs = touching_geom_pairs(result.spec)
    reported = {entry.name for entry in result.approximations + result.unsupported if entry.kind == "contact"}
    static_bodies = {b for b in range(model.nbody) if model.body_weldid[b] == 0}
    geoms = [g for g in range(model.ngeom) if result.mapping.geoms[g] is not None]

    def name(b):
        return model.body(b).name or f"body{b}"

    mismatches = []
    for i, a in enumerate(geoms):
        for b in geoms[i + 1 :]:
            body_a, body_b = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
            if body_a == body_b or (body_a in static_bodies and body_b in static_bodies):
                continue
            if model.geom_type[a] == model.geom_type[b] == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            ta, tb = result.mapping.geoms[a], result.mapping.geoms[b]
            physx = _physx_collides(
                result,
                component_of(result, ta).collision_shapes[ta.shape],
                component_of(result, tb).collision_shapes[tb.shape],
            )
            physx = physx and not _direct_parent_child(result, body_a, body_b)
            pair_names = {f"{name(body_a)}/{name(body_b)}", f"{name(body_b)}/{name(body_a)}"}
            if physx != ((a, b) in mujoco_pairs) and not pair_names & reported:
                mismatches.append((model.geom(a).name or a, model.geom(b).name or b, physx))
    return mismatches
