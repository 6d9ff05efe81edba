"""Spatial tendons on tensors: each carried tendon's length and its Jacobian over the coordinates (env, tendon, n) at
the tree's `motion`, as MuJoCo's `mj_tendon` gives them (the plan: `loader/plan/spatial_tendon.py`), for the joint
actuation law's actuators and springs on them (`joint_actuation.py`).

A segment between two sites with a sphere or cylinder between them wraps as MuJoCo's `mju_wrap` wraps it: both
sites taken into the geom's frame and onto a plane through its centre (a cylinder's xy plane; for a sphere the plane
through both), the two tangent lines from them to the circle, of the two pairs the one nearer the sidesite (without
one, the shorter) and neither crossing the other, no wrap where the straight segment misses the circle (or passes it
on the sidesite's side); a cylinder's tangent points then rise along its axis in proportion to the path's planar
length. Every branch is taken for every env and the env's own kept (`torch.where`): no host decision per step
(tests/test_maniskill_joint_actuation.py::test_spatial_tendons_are_mujocos)."""

from __future__ import annotations

import math

import torch

from ..model.mj import MJMINVAL
from ..plan.spatial_tendon import SpatialTendons
from .inertia import Inertia, Motion, point_jacobians


class SpatialTendonTensors:
    """The plan's segments as tensors."""

    def __init__(self, plan: SpatialTendons, tensor, device):
        def index(array):
            return torch.as_tensor(array, dtype=torch.long, device=device)

        self.any = bool(plan.tendon.size)  # read on the host
        self.count = plan.count
        self.tendon = index(plan.tendon)
        self.links = index(plan.links.reshape(-1))  # (2 segments,): each segment's first site's, then its second's
        self.points = tensor(plan.points.reshape(-1, 3))
        self.scale = tensor(plan.scale)
        self.wraps = index(plan.wrapped.nonzero()[0])  # the segments with a geom between their sites
        wrapped = plan.wrapped
        self.geom_link = index(plan.geom_link[wrapped])
        self.geom_position, self.geom_rotation = (
            tensor(plan.geom_position[wrapped]),
            tensor(plan.geom_rotation[wrapped]),
        )
        self.radius = tensor(plan.radius[wrapped])
        self.sphere = torch.as_tensor(plan.sphere[wrapped], device=device)
        self.sided = torch.as_tensor(plan.sided[wrapped], device=device)
        self.side = tensor(plan.side[wrapped])


def spatial_tendons(tendons: SpatialTendonTensors, law: Inertia, moved: Motion) -> tuple[torch.Tensor, torch.Tensor]:
    """The tendons' lengths (env, tendon) and Jacobians (env, tendon, n) at the tree's `motion`."""
    env, count = moved.origin.shape[0], tendons.scale.shape[0]
    ends = moved.origin[:, tendons.links] + (moved.rotation[:, tendons.links] @ tendons.points[..., None])[..., 0]
    jacobians = point_jacobians(law, moved, tendons.links, ends)
    ends, jacobians = ends.reshape(env, count, 2, 3), jacobians.reshape(env, count, 2, -1, 3)
    first, second = ends[:, :, 0], ends[:, :, 1]
    length, jacobian = _piece(first, second, jacobians[:, :, 0], jacobians[:, :, 1])
    if tendons.wraps.numel():
        wraps = tendons.wraps
        wrapped_length, wrapped_jacobian, wraps_here = _wrapped(
            tendons, law, moved, first[:, wraps], second[:, wraps], jacobians[:, wraps, 0], jacobians[:, wraps, 1]
        )
        length = length.index_copy(1, wraps, torch.where(wraps_here, wrapped_length, length[:, wraps]))
        kept = torch.where(wraps_here[..., None], wrapped_jacobian, jacobian[:, wraps])
        jacobian = jacobian.index_copy(1, wraps, kept)
    length, jacobian = length * tendons.scale, jacobian * tendons.scale[:, None]
    total = length.new_zeros(env, tendons.count).index_add(1, tendons.tendon, length)
    return total, jacobian.new_zeros(env, tendons.count, jacobian.shape[-1]).index_add(1, tendons.tendon, jacobian)


def _piece(start, end, start_jacobian, end_jacobian) -> tuple[torch.Tensor, torch.Tensor]:
    """A straight piece's length (env, k) and the Jacobian of that length (env, k, n): its direction times its ends'
    velocity Jacobians' difference (none where its ends meet)."""
    difference = end - start
    length = torch.linalg.vector_norm(difference, dim=-1)
    direction = difference / torch.clamp(length, min=MJMINVAL)[..., None] * (length >= MJMINVAL)[..., None]
    return length, ((end_jacobian - start_jacobian) * direction[:, :, None, :]).sum(-1)


def _wrapped(tendons, law, moved, first, second, first_jacobian, second_jacobian):
    """The wrapped segments' lengths (env, w) and Jacobians (env, w, n), and where each env's wraps (env, w)."""
    rotation = moved.rotation[:, tendons.geom_link]  # the geom's link, (env, w, 3, 3)
    origin = moved.origin[:, tendons.geom_link] + (rotation @ tendons.geom_position[..., None])[..., 0]
    frame = rotation @ tendons.geom_rotation  # the geom's frame in the world
    local0 = (frame.transpose(-1, -2) @ (first - origin)[..., None])[..., 0]
    local1 = (frame.transpose(-1, -2) @ (second - origin)[..., None])[..., 0]
    axis0, axis1 = _plane(tendons, local0, local1)
    d0 = torch.stack(((local0 * axis0).sum(-1), (local0 * axis1).sum(-1)), -1)
    d1 = torch.stack(((local1 * axis0).sum(-1), (local1 * axis1).sum(-1)), -1)
    tangent0, tangent1, arc, wraps = _circle(d0, d1, tendons.radius, tendons.side, tendons.sided)
    near = (torch.linalg.vector_norm(local0, dim=-1) >= MJMINVAL) & (
        torch.linalg.vector_norm(local1, dim=-1) >= MJMINVAL
    )
    wraps = wraps & near
    point0 = axis0 * tangent0[..., :1] + axis1 * tangent0[..., 1:]
    point1 = axis0 * tangent1[..., :1] + axis1 * tangent1[..., 1:]
    # a cylinder's tangent points rise along its axis with the path's planar length
    before = torch.linalg.vector_norm(local0[..., :2] - point0[..., :2], dim=-1)
    after = torch.linalg.vector_norm(local1[..., :2] - point1[..., :2], dim=-1)
    total = torch.clamp(before + arc + after, min=MJMINVAL)
    rise = local1[..., 2] - local0[..., 2]
    height0, height1 = local0[..., 2] + rise * before / total, local0[..., 2] + rise * (before + arc) / total
    cylinder = ~tendons.sphere
    point0 = torch.where(cylinder[..., None], torch.cat((point0[..., :2], height0[..., None]), -1), point0)
    point1 = torch.where(cylinder[..., None], torch.cat((point1[..., :2], height1[..., None]), -1), point1)
    arc = torch.where(cylinder, torch.sqrt(arc * arc + (height1 - height0) ** 2), arc)
    world0 = origin + (frame @ point0[..., None])[..., 0]
    world1 = origin + (frame @ point1[..., None])[..., 0]
    on_geom = point_jacobians(law, moved, tendons.geom_link.repeat(2), torch.cat((world0, world1), 1))
    jacobian0, jacobian1 = on_geom.split(world0.shape[1], 1)
    length0, moment0 = _piece(first, world0, first_jacobian, jacobian0)
    length1, moment1 = _piece(world1, second, jacobian1, second_jacobian)
    return length0 + arc + length1, moment0 + moment1, wraps


def _normalised(vector: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    norm = torch.linalg.vector_norm(vector, dim=-1, keepdim=True)
    return vector / torch.clamp(norm, min=MJMINVAL), norm[..., 0]


def _plane(tendons, local0, local1) -> tuple[torch.Tensor, torch.Tensor]:
    """The wrap's plane through the geom's centre, two unit axes (env, w, 3): a cylinder's x and y; for a sphere,
    the first site's direction and the normal to both sites turned about it (another normal where they are
    parallel: the first axis crossed with ones but at its largest component)."""
    axis0, _ = _normalised(local0)
    normal, norm = _normalised(torch.linalg.cross(local0, local1))
    largest = torch.nn.functional.one_hot(axis0.abs().argmax(-1), 3).to(axis0.dtype)
    fallback, _ = _normalised(torch.linalg.cross(axis0, 1.0 - largest))
    normal = torch.where((norm < MJMINVAL)[..., None], fallback, normal)
    axis1, _ = _normalised(torch.linalg.cross(normal, axis0))
    x, y = torch.zeros_like(axis0), torch.zeros_like(axis0)
    x[..., 0], y[..., 1] = 1.0, 1.0
    sphere = tendons.sphere[..., None]
    return torch.where(sphere, axis0, x), torch.where(sphere, axis1, y)


def _cross(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """The 2D cross product u_x v_y - u_y v_x (..., 2 -> ...)."""
    return (u * v.flip(-1) * u.new_tensor([1.0, -1.0])).sum(-1)


def _crossing(p1, p2, p3, p4) -> torch.Tensor:
    """Whether the 2D segments p1-p2 and p3-p4 (..., 2) cross: where p1 + a (p2 - p1) = p3 + b (p4 - p3) with a and
    b in [0, 1] (parallel segments never cross)."""
    first, second, between = torch.broadcast_tensors(p2 - p1, p4 - p3, p1 - p3)
    det, a, b = _cross(torch.stack((first, second, first)), torch.stack((second, between, between))).unbind(0)
    safe = torch.where(det.abs() < MJMINVAL, torch.ones_like(det), det)
    a, b = a / safe, b / safe
    return (det.abs() >= MJMINVAL) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)


def _circle(d0, d1, radius, side, sided):
    """MuJoCo's 2D circle wrap of the segment d0-d1 (env, w, 2) about a circle of `radius` at the origin: the two
    tangent points, the arc's length between them and whether it wraps at all. The two candidate pairs of tangent
    points are taken together on a leading axis (MuJoCo's sign +1, then -1)."""
    square = radius * radius
    length0, length1 = (d0 * d0).sum(-1), (d1 * d1).sum(-1)
    difference = d1 - d0
    spread = (difference * difference).sum(-1)
    nearest = torch.clamp(-(difference * d0).sum(-1) / torch.clamp(spread, min=MJMINVAL), 0.0, 1.0)
    closest = d0 + nearest[..., None] * difference
    misses = ((closest * closest).sum(-1) > square) & (~sided | ((side * closest).sum(-1) >= 0))
    wraps = (length0 >= square) & (length1 >= square) & (radius >= MJMINVAL) & (spread >= MJMINVAL) & ~misses
    sign = d0.new_tensor([1.0, -1.0])[:, None, None, None]  # (2, 1, 1, 1): the pair's sign
    turned0 = d0.flip(-1) * d0.new_tensor([1.0, -1.0])  # (d_y, -d_x)
    turned1 = d1.flip(-1) * d1.new_tensor([-1.0, 1.0])  # (-d_y, d_x)
    root0 = torch.sqrt(torch.clamp(length0 - square, min=0.0))[..., None]
    root1 = torch.sqrt(torch.clamp(length1 - square, min=0.0))[..., None]
    scale0, scale1 = torch.clamp(length0, min=MJMINVAL)[..., None], torch.clamp(length1, min=MJMINVAL)[..., None]
    starts = (d0 * square[..., None] + sign * radius[..., None] * turned0 * root0) / scale0  # (2, env, w, 2)
    ends = (d1 * square[..., None] + sign * radius[..., None] * turned1 * root1) / scale1
    towards, _ = _normalised(starts + ends)
    good = torch.where(sided, (towards * side).sum(-1), -((starts - ends) ** 2).sum(-1))
    good = torch.where(_crossing(d0, starts, d1, ends), torch.full_like(good, -10000.0), good)
    second = ~(good[0] > good[1])  # MuJoCo's index 1
    start = torch.where(second[..., None], starts[1], starts[0])
    end = torch.where(second[..., None], ends[1], ends[0])
    wraps = wraps & ~_crossing(d0, start, d1, end)
    unit0, _ = _normalised(start)
    unit1, _ = _normalised(end)
    angle = torch.acos(torch.clamp((unit0 * unit1).sum(-1), -1.0, 1.0))
    turn = start[..., 1] * end[..., 0] - start[..., 0] * end[..., 1]
    flipped = ((turn > 0) & second) | ((turn < 0) & ~second)
    angle = torch.where(flipped, 2.0 * math.pi - angle, angle)
    return start, end, radius * angle, wraps
