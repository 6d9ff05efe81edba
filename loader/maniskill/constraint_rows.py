"""MuJoCo's constraint rows in the joint actuation law on tensors (`joint_actuation.py`): the limit and frictionloss
rows of the robot's hinges and slides and of the fixed tendons over them, and the couplings (joint and fixed-tendon
equalities), each with the reference acceleration and weight MuJoCo's solref and solimp give it, solved as MuJoCo's
Newton solver solves them, from the smooth force, with the law's M. Every row's position is linear in q (a joint's
position, a fixed tendon's length: its coefficients times q), so each row's Jacobian is a constant of the plan
(tests/test_maniskill_joint_actuation.py::test_the_laws_limit_rows_are_mujocos and the row tests after it)."""

from __future__ import annotations

import copy

import numpy as np
import torch

from ..model.frames import quat_to_mat
from ..model.mj import MJMINVAL
from ..model.soft_row import MAXIMP, MINIMP
from ..plan.joint_actuation import JointFriction, JointLimits
from .inertia import points_and_jacobians, turning

# the rows' solve: passes of taking each row's zone at an acceleration, solving on them and stepping towards that
# solution, a fixed count so that the device never waits on the host (twice what the law's row tests need:
# tests/test_maniskill_joint_actuation.py::test_the_laws_frictionloss_rows_are_mujocos), each step the cheapest of
# ROW_STEPS
ROW_PASSES = 10
ROW_STEPS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.0)


class Solimp:
    """solimp (5, rows) as tensors, clamped as MuJoCo clamps them; called on a violation r (..., rows): MuJoCo's
    impedance imp(|r|), its sigmoid from dmin at r = 0 to dmax at |r| >= width."""

    def __init__(self, solimp: np.ndarray, tensor):
        low = [[MINIMP], [MINIMP], [-np.inf], [MJMINVAL], [1.0]]
        high = [[MAXIMP], [MAXIMP], [np.inf], [1 - MJMINVAL], [np.inf]]
        clamped = np.clip(np.asarray(solimp, np.float64), low, high)
        self.low, self.high, self.width, self.midpoint, self.power = (tensor(x) for x in clamped)
        self.flat = tensor((clamped[0] == clamped[1]) | (clamped[2] <= MJMINVAL)) > 0

    def __call__(self, violation: torch.Tensor) -> torch.Tensor:
        x = torch.clamp(torch.abs(violation) / torch.clamp(self.width, min=MJMINVAL), max=1.0)
        midpoint, power = self.midpoint, self.power
        rising = x**power / midpoint ** (power - 1.0)
        falling = 1.0 - (1.0 - x) ** power / (1.0 - midpoint) ** (power - 1.0)
        imp = self.low + torch.where(x <= midpoint, rising, falling) * (self.high - self.low)
        return torch.where(self.flat, 0.5 * (self.low + self.high), imp)


class RowSet:
    """The limit and frictionloss rows of one kind of owner, a robot DoF or a fixed tendon: per owner its lower and
    upper limit rows and its frictionloss row, (3, owners), on the owner's position, linear in q (`jacobian`
    (owners, DoF), its coefficients; None: the DoFs themselves). A lower limit row pushes up, an upper one down
    (`sign`); a limit's force is bounded from zero, frictionloss's within +-loss."""

    def __init__(self, limits: JointLimits, friction: JointFriction, jacobian: np.ndarray | None, tensor, device):
        self.jacobian = None if jacobian is None else tensor(jacobian)
        self.limited = torch.as_tensor(limits.limited, device=device)
        self.low, self.high, self.margin = (tensor(x) for x in (*limits.range, limits.margin))
        self.stiffness, self.damping = tensor(limits.stiffness), tensor(limits.damping)
        self.diag = tensor(limits.diag_approx)
        self.imp = Solimp(limits.solimp, tensor)
        self.friction_damping, self.friction_weight = tensor(friction.damping), tensor(friction.weight)
        self.present = bool(limits.limited.any() or np.any(friction.loss > 0))  # read on the host
        self.sign = tensor([[1.0], [-1.0], [1.0]])
        loss = np.asarray(friction.loss, np.float64)
        self.bound_low = tensor(np.stack((np.zeros_like(loss), np.zeros_like(loss), -loss)))
        self.bound_high = tensor(np.stack((np.full_like(loss, np.inf), np.full_like(loss, np.inf), loss)))

    def along(self, x: torch.Tensor) -> torch.Tensor:
        """(..., DoF) -> (..., owners): J x, the owners' share of a joint-space vector (a position, a velocity)."""
        return x if self.jacobian is None else x @ self.jacobian.T

    def back(self, y: torch.Tensor) -> torch.Tensor:
        """(..., owners) -> (..., DoF): J^T y, the joint force of the owners' forces."""
        return y if self.jacobian is None else y @ self.jacobian

    def curvature(self, weight: torch.Tensor) -> torch.Tensor:
        """(env, owners) -> (env, DoF, DoF): J^T diag(weight) J."""
        if self.jacobian is None:
            return torch.diag_embed(weight)
        return (self.jacobian.T * weight[:, None, :]) @ self.jacobian

    def state(self, q: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The owners' positions and velocities (env, owners) at the joints' q and v."""
        return self.along(q), self.along(v)

    def at(self, q: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The rows at the state, (env, 3, owners) each: their reference accelerations aref (a limit's
        -B J v - K imp (r - margin), frictionloss's -B J v) and weights D (zero where a row is absent: a limit beyond
        its margin, an owner without frictionloss)."""
        position, velocity = self.state(q, v)
        distance = torch.stack((position - self.low, self.high - position), 1)  # (env, 2, owners)
        present = self.limited & (distance < self.margin)
        violation = distance - self.margin
        imp = self.imp(violation)
        limit_aref = -self.damping * self.sign[:2] * velocity[:, None] - self.stiffness * imp * violation
        limit_weight = present / torch.clamp((1.0 - imp) * self.diag / imp, min=MJMINVAL)
        aref = torch.cat((limit_aref, (-self.friction_damping * velocity)[:, None]), 1)
        weight = torch.cat((limit_weight, self.friction_weight.expand_as(velocity)[:, None]), 1)
        return aref, weight


class SpatialRowSet(RowSet):
    """The limit and frictionloss rows of spatial tendons: a fixed tendon's rows, on a length and a Jacobian that
    change with the pose, taken each step from the tendons at the state (`bound`)."""

    def bound(self, length: torch.Tensor, jacobian: torch.Tensor, v: torch.Tensor) -> SpatialRowSet:
        """These rows at the tendons' lengths (env, owners) and Jacobians over the joints (env, owners, DoF), the
        joints moving at v."""
        rows = copy.copy(self)
        rows.length, rows.moment = length, jacobian
        rows.rate = (jacobian @ v[..., None])[..., 0]
        return rows

    def state(self, q: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.length, self.rate

    def along(self, x: torch.Tensor) -> torch.Tensor:
        """(env, DoF) or (env, k, DoF) -> (env, owners) or (env, k, owners): J x, per env."""
        across = self.moment.transpose(-1, -2)
        return x @ across if x.dim() == 3 else (x[:, None] @ across)[:, 0]

    def back(self, y: torch.Tensor) -> torch.Tensor:
        return (y[:, None] @ self.moment)[:, 0]

    def curvature(self, weight: torch.Tensor) -> torch.Tensor:
        return (self.moment.transpose(-1, -2) * weight[:, None, :]) @ self.moment


def _row_cost(weight, low, high, miss: torch.Tensor) -> torch.Tensor:
    """The rows' cost summed (..., 3, owners -> ...) at their misses J a - aref: D/2 miss^2 while the force -D miss
    is within its bounds, linear beyond (the force held at the bound)."""
    force = torch.clamp(-weight * miss, low, high)
    cost = -force * miss - force * force / (2.0 * torch.clamp(weight, min=MJMINVAL))
    return torch.where(weight > 0, cost, 0.0).sum((-2, -1))


class Couplings:
    """The couplings' arrays (`plan.joint_actuation.JointCouplings`) as tensors."""

    def __init__(self, couplings, tensor):
        self.any = bool(couplings.first.shape[0])  # read on the host
        # (rows, DoF): each row's two joint positions or fixed tendon lengths as coefficients over the DoFs
        self.first, self.second = tensor(couplings.first), tensor(couplings.second)
        self.origin, self.poly = tensor(couplings.origin), tensor(couplings.poly)
        self.stiffness, self.damping = tensor(couplings.stiffness), tensor(couplings.damping)
        self.diag = tensor(couplings.diag_approx)
        self.imp = Solimp(couplings.solimp, tensor)

    def at(self, q: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The rows at the state: their Jacobians (env, rows, DoF), reference accelerations aref = -B J v - K imp r
        and weights D (env, rows), r = L1 - L1_0 - poly(L2 - L2_0)."""
        first = q @ self.first.T - self.origin[0]  # (env, rows)
        second = q @ self.second.T - self.origin[1]  # zero where a row has no second end
        poly = self.poly
        value = poly[0] + second * (poly[1] + second * (poly[2] + second * (poly[3] + second * poly[4])))
        slope = poly[1] + second * (2.0 * poly[2] + second * (3.0 * poly[3] + second * 4.0 * poly[4]))
        violation = first - value
        jacobian = self.first - slope[..., None] * self.second
        imp = self.imp(violation)
        aref = -self.damping * (jacobian @ v[..., None])[..., 0] - self.stiffness * imp * violation
        weight = imp / torch.clamp((1.0 - imp) * self.diag, min=MJMINVAL)
        return jacobian, aref, weight


class Connects:
    """The connects' arrays (`plan.joint_actuation.Connects`) as tensors."""

    def __init__(self, connects, tensor, device):
        self.any = bool(connects.links.shape[0])  # read on the host
        self.links = torch.as_tensor(connects.links.reshape(-1), dtype=torch.long, device=device)  # (2n,)
        self.points = tensor(connects.points.reshape(-1, 3))
        self.stiffness, self.damping = tensor(connects.stiffness), tensor(connects.damping)
        self.diag = tensor(connects.diag_approx)
        self.imp = Solimp(connects.solimp, tensor)

    def at(self, inertia, moved, v: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The rows at the state (the tree's `motion`, joint velocities v): their Jacobians (env, 3n, n), reference
        accelerations
        aref = -B J v - K imp r - dJ/dt v and weights D (env, 3n), r = p1 - p2 the anchors' separation, imp taken at
        |r|, dJ/dt v what the velocities alone accelerate r by (MuJoCo's correction of a connect's reference)."""
        points, jacobians, rates = points_and_jacobians(inertia, moved, v, self.links, self.points)
        env, count = v.shape[0], self.stiffness.shape[0]
        points, rates = points.reshape(env, count, 2, 3), rates.reshape(env, count, 2, 3)
        jacobians = jacobians.reshape(env, count, 2, -1, 3)
        separation = points[:, :, 0] - points[:, :, 1]  # (env, n, 3)
        jacobian = (jacobians[:, :, 0] - jacobians[:, :, 1]).transpose(-1, -2)  # (env, n, 3, DoF)
        imp = self.imp(torch.linalg.vector_norm(separation, dim=-1))[..., None]  # (env, n, 1)
        speed = (jacobian @ moved.speed[:, None, :, None])[..., 0]  # (env, n, 3)
        aref = -self.damping[:, None] * speed - self.stiffness[:, None] * imp * separation
        aref = aref - (rates[:, :, 0] - rates[:, :, 1])
        weight = imp / torch.clamp((1.0 - imp) * self.diag, min=MJMINVAL)
        return jacobian.reshape(env, 3 * count, -1), aref.reshape(env, -1), weight.reshape(env, -1)


def _product(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The quaternion product a b (..., 4: w, x, y, z)."""
    aw, av, bw, bv = a[..., :1], a[..., 1:], b[..., :1], b[..., 1:]
    return torch.cat((aw * bw - (av * bv).sum(-1, keepdim=True), aw * bv + bw * av + torch.linalg.cross(av, bv)), -1)


def _pure(vector: torch.Tensor) -> torch.Tensor:
    return torch.nn.functional.pad(vector, (1, 0))


def _quaternion(rotation: torch.Tensor) -> torch.Tensor:
    """A rotation matrix's unit quaternion (..., 4), its real part non-negative (the error rows' sign does not
    matter: their Jacobian and reference flip with them)."""
    w = 0.5 * torch.sqrt(torch.clamp(1.0 + rotation.diagonal(dim1=-2, dim2=-1).sum(-1), min=0.0))
    vector = (
        torch.stack(
            (
                rotation[..., 2, 1] - rotation[..., 1, 2],
                rotation[..., 0, 2] - rotation[..., 2, 0],
                rotation[..., 1, 0] - rotation[..., 0, 1],
            ),
            -1,
        )
        / (4.0 * torch.clamp(w, min=MJMINVAL))[..., None]
    )
    return torch.cat((w[..., None], vector), -1)


class Welds:
    """The welds' arrays (`plan.joint_actuation.Welds`) as tensors."""

    def __init__(self, welds, tensor, device):
        self.any = bool(welds.links.shape[0])  # read on the host
        self.links = torch.as_tensor(welds.links.reshape(-1), dtype=torch.long, device=device)  # (2n,)
        self.points = tensor(welds.points.reshape(-1, 3))
        self.relative = tensor(np.array([quat_to_mat(q) for q in welds.relative]).reshape(-1, 3, 3))  # relpose's
        self.scale = tensor(welds.torquescale)
        self.stiffness, self.damping = tensor(welds.stiffness), tensor(welds.damping)
        self.diag = tensor(welds.diag_approx)
        self.imp = Solimp(welds.solimp, tensor)

    def at(self, inertia, moved, v: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The rows at the state (the tree's `motion`, joint velocities v): their Jacobians (env, 6n, n), reference
        accelerations aref = -B J v - K imp r - dJ/dt v and weights D (env, 6n): three on the points' separation (as
        a connect's), three on torquescale times the vector part of e = conj(q2) q1 relpose, with MuJoCo's Jacobian
        0.5 (0, R2^T dw) e and its rate."""
        env, count = v.shape[0], self.stiffness.shape[0]
        points, jacobians, rates = points_and_jacobians(inertia, moved, v, self.links, self.points)
        points, rates = points.reshape(env, count, 2, 3), rates.reshape(env, count, 2, 3)
        jacobians = jacobians.reshape(env, count, 2, -1, 3)
        rotation, spin_jacobian, spin, spin_rate = turning(inertia, moved, v, self.links)
        rotation, spin = rotation.reshape(env, count, 2, 3, 3), spin.reshape(env, count, 2, 3)
        spin_jacobian, spin_rate = spin_jacobian.reshape(env, count, 2, -1, 3), spin_rate.reshape(env, count, 2, 3)
        back = rotation[:, :, 1].transpose(-1, -2)  # R2^T
        error = _quaternion(back @ rotation[:, :, 0] @ self.relative)  # e, (env, n, 4)
        scale = self.scale[:, None]
        # d e/dt's vector part per unit of a vector u: 0.5 vec((0, u) e) = 0.5 (w u - v x u)
        turned = (back @ (spin_jacobian[:, :, 0] - spin_jacobian[:, :, 1]).transpose(-1, -2)).transpose(-1, -2)
        w, vector = error[..., None, :1], error[..., None, 1:]
        rotational = 0.5 * scale[..., None] * (w * turned - torch.linalg.cross(vector.expand_as(turned), turned))
        # e's rate along the motion, in body2's frame: (0, R2^T w) conj(q2) = conj(q2) (0, w), q' = 0.5 (0, w) q
        spins = (back[:, :, None] @ spin[..., None])[..., 0]  # R2^T w1, R2^T w2
        spun = _pure(spins[:, :, 0] - spins[:, :, 1])  # R2^T dw
        terms = (
            -0.5 * _product(_product(_pure(spins[:, :, 1]), spun), error)
            + _product(_pure((back @ (spin_rate[:, :, 0] - spin_rate[:, :, 1])[..., None])[..., 0]), error)
            + 0.5 * _product(_product(spun, _pure(spins[:, :, 0])), error)
        )
        separation = points[:, :, 0] - points[:, :, 1]
        residual = torch.cat((separation, scale * error[..., 1:]), -1)  # (env, n, 6)
        jacobian = torch.cat(((jacobians[:, :, 0] - jacobians[:, :, 1]), rotational), -1).transpose(-1, -2)
        imp = self.imp(torch.linalg.vector_norm(residual, dim=-1))[..., None]
        speed = (jacobian @ moved.speed[:, None, :, None])[..., 0]  # (env, n, 6)
        rate = torch.cat((rates[:, :, 0] - rates[:, :, 1], 0.5 * scale * terms[..., 1:]), -1)
        aref = -self.damping[:, None] * speed - self.stiffness[:, None] * imp * residual - rate
        weight = imp / torch.clamp((1.0 - imp) * self.diag, min=MJMINVAL)
        return jacobian.reshape(env, 6 * count, -1), aref.reshape(env, -1), weight.reshape(env, -1)


def constraint_force(
    law,
    matrix: torch.Tensor,
    q: torch.Tensor,
    v: torch.Tensor,
    smooth: torch.Tensor,
    inertia=None,
    moved=None,
    spatial=None,
) -> torch.Tensor:
    """MuJoCo's constraint force (env, n) of the law's rows at the state (`law.couplings`, `law.connects`,
    `law.row_sets`), from the smooth force `smooth` (env, n: f - c, a floating root's six coordinates first): M a -
    smooth at the acceleration a MuJoCo's solver finds. The equality rows (couplings; connects and welds, on the
    tree's `motion` at the state, `moved`), two-sided and unbounded, add J^T D J to M and J^T D aref to the smooth
    force, and the limit and frictionloss rows are solved on those (`_row_solve`)."""
    rows, root = [], matrix.shape[-1] - q.shape[-1]
    if law.couplings.any:  # over the joints alone: no force on a floating root's coordinates
        jacobian, aref, weight = law.couplings.at(q, v)
        rows.append((torch.nn.functional.pad(jacobian, (root, 0)), aref, weight))
    if law.connects.any:
        rows.append(law.connects.at(inertia, moved, v))
    if law.welds.any:
        rows.append(law.welds.at(inertia, moved, v))
    coupled, pulled = matrix, smooth
    if rows:
        jacobian = torch.cat([j for j, _, _ in rows], 1)
        aref, weight = torch.cat([a for _, a, _ in rows], 1), torch.cat([w for _, _, w in rows], 1)
        weighted = jacobian.transpose(-1, -2) * weight[:, None, :]  # J^T D
        coupled, pulled = matrix + weighted @ jacobian, smooth + (weighted @ aref[..., None])[..., 0]
    sets = law.row_sets
    if law.spatial_rows.present:  # on the spatial tendons at the state (`joint_actuation.Spatial`)
        sets = [*sets, law.spatial_rows.bound(spatial.length[:, law.rowed], spatial.jacobian[:, law.rowed, root:], v)]
    acceleration = _row_solve(sets, law.row_steps, coupled, q, v, pulled)
    if acceleration is None:  # no limit or frictionloss row present
        if not rows:
            return torch.zeros_like(smooth)
        acceleration = torch.linalg.solve_ex(coupled, pulled)[0]
    return (matrix @ acceleration[..., None])[..., 0] - smooth


def _row_solve(
    sets: list[RowSet], steps: torch.Tensor, matrix: torch.Tensor, q: torch.Tensor, v: torch.Tensor, smooth
) -> torch.Tensor | None:
    """The acceleration (env, n) MuJoCo's Newton solver finds with the limit and frictionloss rows of `sets` on the
    quadratic M, smooth (the couplings folded in): the a minimising M's norm of its change from M^-1 smooth plus each
    row's cost, D/2 (J a - aref)^2 where its force -D (J a - aref) is within its bounds and linear beyond. Each pass
    takes each row's zone (within, or held at a bound) at a, solves (M + J^T D J) a' = smooth + J^T (D aref + held
    force) over the rows within, and moves a towards a' by the step of `steps` (`ROW_STEPS`) that costs least (a
    full step can cross a zone and come back: frictionloss holding a joint still). ROW_PASSES passes; on the CPU,
    where a check costs no wait on a device, until a full step leaves the zones as they were, and None where no row
    is present."""
    root = matrix.shape[-1] - q.shape[-1]
    rows = [(owners, *owners.at(q, v)) for owners in sets]
    host = matrix.device.type == "cpu"  # where a check costs no wait on a device
    if host and not any(bool((weight > 0).any()) for _, _, weight in rows):
        return None
    free = torch.linalg.solve_ex(matrix, smooth)[0]
    pad = torch.nn.functional.pad

    def rooted(x: torch.Tensor, square: bool) -> torch.Tensor:  # over the joints -> over every coordinate
        return x if not root else pad(x, (root, 0, root, 0) if square else (root, 0))

    acceleration, taken, full = free, None, False
    steps, envs = steps[:, None], torch.arange(matrix.shape[0], device=matrix.device)  # (steps, 1), (env,)
    for _ in range(ROW_PASSES):
        stiffened, pulled, zones = matrix, smooth, []
        for owners, aref, weight in rows:
            force = -weight * (owners.sign * owners.along(acceleration[:, root:])[:, None] - aref)
            within = (force > owners.bound_low) & (force < owners.bound_high)
            if host:  # the zones decide only the host's early stop
                zones.append(torch.where(within, 0, torch.where(force >= owners.bound_high, 1, -1)).flatten(1))
            held = torch.where(within, 0.0, torch.clamp(force, owners.bound_low, owners.bound_high))
            stiffness = weight * within  # a row's J is its owner's, up to its sign: their D summed per owner
            stiffened = stiffened + rooted(owners.curvature(stiffness.sum(1)), True)
            pulled = pulled + rooted(owners.back((owners.sign * (stiffness * aref + held)).sum(1)), False)
        if host:
            zones = torch.cat(zones, 1)
            if full and torch.equal(zones, taken):
                break  # a full step left the zones as they were: the solution stands
            taken = zones
        newton = torch.linalg.solve_ex(stiffened, pulled)[0]
        trial = acceleration[:, None] + steps * (newton - acceleration)[:, None]  # (env, steps, n)
        change = trial - free[:, None]
        cost = 0.5 * torch.einsum("esi,eij,esj->es", change, matrix, change)
        for owners, aref, weight in rows:
            miss = owners.sign * owners.along(trial[:, :, root:])[:, :, None] - aref[:, None]  # (env, steps, 3, own)
            cost = cost + _row_cost(weight[:, None], owners.bound_low, owners.bound_high, miss)
        best = cost.argmin(1)
        acceleration = trial[envs, best]
        full = host and bool((best == 0).all())
    return acceleration
