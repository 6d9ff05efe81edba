"""MuJoCo's spatial tendons as the joint actuation law carries them on tensors (`loader/maniskill/spatial_tendons.py`):
each tendon a chain of segments between consecutive sites, straight, or wrapped around the sphere or cylinder between
them where MuJoCo's `mju_wrap` wraps it, each scaled by 1 / the divisor of the last pulley before it. The length is
the segments' summed, and its Jacobian the segments' direction times their ends' velocity Jacobians (a wrapped
segment: the two straight pieces to and from the tangent points, which move with the geom's link; the arc between
them adds length only), as MuJoCo's `mj_tendon` has them. Planned once: each site and geom on its robot link, in that
link's frame; a sidesite as the point on the circle it selects, in the cylinder's plane
(tests/test_maniskill_joint_actuation.py::test_spatial_tendons_are_mujocos)."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..model.frames import quat_to_mat

SITE, PULLEY = int(mujoco.mjtWrap.mjWRAP_SITE), int(mujoco.mjtWrap.mjWRAP_PULLEY)
SPHERE, CYLINDER = int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER)


@dataclass
class SpatialTendons:
    """The carried spatial tendons' segments, flat over all of them (`tendon`: each one's tendon, an index into
    `tendons`, MuJoCo's ids)."""

    tendons: list[int] = field(default_factory=list)
    tendon: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    links: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), int))  # the two sites' robot links
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))  # the sites in their links' frames
    scale: np.ndarray = field(default_factory=lambda: np.zeros(0))  # 1 / the pulley's divisor
    wrapped: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # a sphere or cylinder between them
    geom_link: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    geom_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # in its link's frame
    geom_rotation: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sphere: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # else a cylinder
    sided: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    side: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # the sidesite's point on the circle

    @property
    def count(self) -> int:
        return len(self.tendons)


def why_outside(model: mujoco.MjModel, tendon: int, link_of_body: dict[int, int]) -> str | None:
    """Why the law cannot carry spatial tendon `tendon` on the robot's links, or None."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, tendon) or f"#{tendon}"
    wraps = range(int(model.tendon_adr[tendon]), int(model.tendon_adr[tendon] + model.tendon_num[tendon]))
    for w in wraps:
        kind, target = int(model.wrap_type[w]), int(model.wrap_objid[w])
        if kind == SITE and int(model.site_bodyid[target]) not in link_of_body:
            return f"spatial tendon {name!r} runs through a site outside the robot"
        if kind not in (SPHERE, CYLINDER):
            continue
        body, side = int(model.geom_bodyid[target]), int(model.wrap_prm[w])
        if body not in link_of_body:
            return f"spatial tendon {name!r} wraps a geom outside the robot"
        if side < 0:
            continue
        if kind == SPHERE:
            return f"spatial tendon {name!r} wraps a sphere on a sidesite (its side in the wrap's plane moves)"
        if int(model.site_bodyid[side]) != body:
            return f"spatial tendon {name!r} has a sidesite on another body than its geom's"
        if np.linalg.norm(_in_geom(model, target, model.site_pos[side])[:2]) < model.geom_size[target][0]:
            return f"spatial tendon {name!r} has a sidesite inside its cylinder (MuJoCo's inside wrap)"
    return None


def _in_geom(model: mujoco.MjModel, geom: int, point: np.ndarray) -> np.ndarray:
    """A point of the geom's body's frame in the geom's frame."""
    return quat_to_mat(model.geom_quat[geom]).T @ (np.asarray(point, np.float64) - model.geom_pos[geom])


def _segments(model: mujoco.MjModel, tendon: int):
    """The tendon's segments as MuJoCo's `mj_tendon` walks its path: (first site, geom wrap or -1, second site, scale)
    for each pair of sites with at most a sphere or cylinder between them; a pulley scales the segments after it."""
    start, count = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    scale, out = 1.0, []
    for w in range(start, start + count - 1):
        kind, after = int(model.wrap_type[w]), int(model.wrap_type[w + 1])
        if kind == PULLEY:
            scale = 1.0 / float(model.wrap_prm[w])
            continue
        if kind != SITE or after == PULLEY:
            continue
        if after == SITE:
            out.append((int(model.wrap_objid[w]), -1, -1, int(model.wrap_objid[w + 1]), scale))
        else:  # a geom, then the site after it
            side = int(model.wrap_prm[w + 1])
            out.append((int(model.wrap_objid[w]), w + 1, side, int(model.wrap_objid[w + 2]), scale))
    return out


def plan_spatial_tendons(model: mujoco.MjModel, tendons: list[int], link_of_body: dict[int, int]) -> SpatialTendons:
    """The segments of `tendons` (each carried: `why_outside` is None), in that order."""
    rows = []
    for index, tendon in enumerate(tendons):
        for first, wrap, side, second, scale in _segments(model, tendon):
            rows.append((index, first, wrap, side, second, scale))
    if not rows:
        return SpatialTendons(list(tendons))
    count = len(rows)
    plan = SpatialTendons(
        list(tendons),
        np.array([row[0] for row in rows], int),
        np.zeros((count, 2), int),
        np.zeros((count, 2, 3)),
        np.array([row[5] for row in rows], float),
        np.zeros(count, bool),
        np.zeros(count, int),
        np.zeros((count, 3)),
        np.tile(np.eye(3), (count, 1, 1)),
        np.zeros(count),
        np.zeros(count, bool),
        np.zeros(count, bool),
        np.zeros((count, 2)),
    )
    for k, (_, first, wrap, side, second, _) in enumerate(rows):
        for end, site in enumerate((first, second)):
            plan.links[k, end] = link_of_body[int(model.site_bodyid[site])]
            plan.points[k, end] = model.site_pos[site]
        if wrap < 0:
            continue
        geom = int(model.wrap_objid[wrap])
        plan.wrapped[k], plan.geom_link[k] = True, link_of_body[int(model.geom_bodyid[geom])]
        plan.geom_position[k], plan.geom_rotation[k] = model.geom_pos[geom], quat_to_mat(model.geom_quat[geom])
        plan.radius[k], plan.sphere[k] = model.geom_size[geom][0], int(model.wrap_type[wrap]) == SPHERE
        if side >= 0:  # a cylinder's, on the geom's body and outside it: the point on the circle it selects
            flat = _in_geom(model, geom, model.site_pos[side])[:2]
            plan.sided[k], plan.side[k] = True, flat / np.linalg.norm(flat) * plan.radius[k]
    return plan
