"""MuJoCo's soft joint limits on the joint's PhysX drive: a one-sided limit row as a drive with damping
s / (R dt), a force limit L sized to the row's force bound and an explicit offset, PhysX's hard limit widened out
of the rows' way while `set_ctrl` runs. Frictional and coupled joints keep the hard limit (listed). Derivation:
docs/mapping.md#joint-limits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import mj
from ..build.mapping import Mapping
from ..drive import DofDrive
from ..errors import Notes
from ..soft_row import SoftRow
from .dof_step import ArmatureWriter, DofKey, Step

WIDEN = 0.25  # PhysX's hard limit sits this fraction of the range (at least 0.1 rad or m) beyond MuJoCo's ends
ACCELERATION_BOUND = 100.0  # the row force covers row accelerations up to this (rad/s^2 or m/s^2) ...
MINIMUM_LIMIT = 1.0  # ... and is never below this (N or N m)


def force_limit(damping: float, target: float, v: float, timestep: float) -> float:
    """The drive's force limit L for a row whose force is damping * (target - v_end), from the step's start v:
    the total force clamp(row, 0, 2 L) covers row accelerations up to `ACCELERATION_BOUND`, and no more. The
    explicit offset of L must be cancelled by PhysX's drive inside one solve, and with contacts in the same
    solve PhysX leaves a residual that grows with L: sized on |target| + |v| (a speed, not the row's force), L
    blew dm_control's humanoid up as it collapsed onto the floor
    (tests/test_loader_limit.py::test_limit_rows_under_contact_stay_finite)."""
    return max(MINIMUM_LIMIT, 0.5 * damping * (abs(target - v) + timestep * ACCELERATION_BOUND))


@dataclass(frozen=True)
class LimitRow:
    """MuJoCo's limit rows of one hinge/slide DoF."""

    lower: float
    upper: float
    margin: float
    row: SoftRow
    diag_approx: float  # MuJoCo's diagApprox of the row: dof_invweight0
    inverse_inertia: float  # (M^-1)_ii at qpos0, for the damping scale s
    armature: float  # the joint's own armature

    def scale(self, implicit_damping: float, timestep: float) -> float:
        return 1.0 + self.inverse_inertia * timestep * implicit_damping

    def active(self, q: float) -> tuple[float, float] | None:
        """(sign, r) of the row that exists at q (r = q - lower or upper - q), or None."""
        below, above = q - self.lower, self.upper - q
        if below < self.margin and below <= above:
            return 1.0, below
        if above < self.margin:
            return -1.0, above
        return None

    def drive(self, q: float, v: float, timestep: float, scale: float) -> tuple[DofDrive, float, float] | None:
        """For this step: the drive, its constant (damping times the velocity target) and the explicit force, or
        None when no row exists."""
        found = self.active(q)
        if found is None:
            return None
        sign, r = found
        imp = self.row.impedance(abs(r - self.margin))
        damping = scale / (self.row.regularizer(imp, self.diag_approx) * timestep)
        row_velocity = sign * v
        target = sign * (row_velocity + timestep * float(self.row.reference(imp, r - self.margin, row_velocity))
                         / scale)
        limit = force_limit(damping, target, v, timestep)
        return DofDrive(0.0, damping, 0.0, limit), damping * target - sign * limit, sign * limit

    def physx_limits(self) -> tuple[float, float]:
        """PhysX's hard limit while the rows are emulated: widened out of their way."""
        widen = max(0.1, WIDEN * (self.upper - self.lower))
        return self.lower - widen, self.upper + widen


@dataclass
class LimitTerm:
    """The soft limit rows of every limited hinge/slide DoF that carries nothing else at its ends: a DoF past an
    end (within its margin) has its row on the drive this step, its other terms in the armature form. PhysX's
    hard limit of those DoFs is widened out of the rows' way while the term runs (`hold`)."""

    rows: dict[DofKey, LimitRow]
    armature: ArmatureWriter = field(default_factory=ArmatureWriter)
    soft: bool = False  # PhysX's hard limits are widened
    name: str = "limits"

    def __post_init__(self) -> None:
        keys = list(self.rows)
        self._keys = keys
        self._low = np.array([self.rows[k].lower + self.rows[k].margin for k in keys])
        self._high = np.array([self.rows[k].upper - self.rows[k].margin for k in keys])

    def contribute(self, step: Step) -> None:
        if not self.soft:
            self.hold(step.joints, soft=True)
        for key in self.near(step.q):
            row, record = self.rows[key], step.dofs[key]
            art, dof = key
            law = record.law
            found = row.drive(step.q[art][dof], step.v[art][dof], step.timestep,
                              row.scale(law.damping + record.implicit_extra, step.timestep))
            if found is None:  # clear of its ends: the joint's own armature back, nothing to remember
                self.armature.set(step.joints[art][dof], key, row.armature, row.armature)
                self.armature.written.pop(key, None)
                continue
            self.armature.armature_form(step, key, row.armature, law, record.constant)
            step.add(key, found[2])
            record.law, record.constant = found[0], found[1]

    def near(self, q) -> list[DofKey]:
        """The DoFs to visit this step: past an end (within its margin), or whose armature still holds a row's
        implicit damping from an earlier step (vectorised: most joints are clear)."""
        values = np.array([q[art][dof] for art, dof in self._keys])
        near = (values < self._low) | (values > self._high)
        return [k for k, hit in zip(self._keys, near) if hit or k in self.armature.written]

    def hold(self, joints, soft: bool) -> None:
        """PhysX's hard limit of every DoF with soft rows: widened out of the rows' way (`soft`), or at MuJoCo's
        range (for callers that do not call `set_ctrl`, and while the term is switched off)."""
        for (art, dof), row in self.rows.items():
            low, high = row.physx_limits() if soft else (row.lower, row.upper)
            joints[art][dof].set_limit(np.array([[low, high]], np.float32))
        self.soft = soft

    def release(self, joints) -> None:
        for (art, dof), row in self.rows.items():
            joints[art][dof].set_armature(np.array([row.armature], np.float32))
        self.hold(joints, soft=False)
        self.armature.written.clear()

    removed = release  # switched off: PhysX's hard limit at MuJoCo's range, as with no rows at all


def coupled_joints(model: mujoco.MjModel) -> set[int]:
    """Joints another constraint row couples to: in a joint or tendon equality, or on a tendon. MuJoCo solves
    their limit rows together with those rows, which a per-DoF drive cannot see (the panda's fingers, held against
    their limits by a tendon servo and coupled by an equality, are closer to MuJoCo with PhysX's hard limit:
    tests/test_loader_actuators.py::test_panda_finger_tendon_and_equality_hold_while_closing), so they keep it."""
    out = set()
    for e in range(model.neq):
        if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT):
            out.update(int(i) for i in (model.eq_obj1id[e], model.eq_obj2id[e]) if i >= 0)
    for w in range(model.nwrap):
        if int(model.wrap_type[w]) == int(mujoco.mjtWrap.mjWRAP_JOINT):
            out.add(int(model.wrap_objid[w]))
    return out


def limit_rows(model: mujoco.MjModel, mapping: Mapping, notes: Notes) -> dict[tuple[int, int], LimitRow]:
    """MuJoCo's limit rows for every limited hinge/slide DoF without frictionloss and not coupled to other rows
    (`coupled_joints`), by (articulation, SAPIEN dof)."""
    if mj.disabled(model, "limit", "constraint"):
        return {}
    limited = [j for j, target in enumerate(mapping.joints)
               if model.jnt_limited[j] and target.kind in ("hinge", "slide")]
    if not limited:
        return {}
    inverse = np.diag(mj.inverse_inertia(model, mj.forward_at(model)))
    coupled = coupled_joints(model)
    out = {}
    for j in limited:
        target, dof = mapping.joints[j], int(model.jnt_dofadr[j])
        why = ("the joint's drive carries its frictionloss" if model.dof_frictionloss[dof] > 0 else
               "an equality or tendon couples the joint" if j in coupled else "")
        if why:
            notes.approximate("joint", mj.name(model, "joint", j), f"limit kept as PhysX's hard limit: {why} "
                              "(MuJoCo's limit is soft: solreflimit)")
            continue
        lower, upper = (float(x) for x in model.jnt_range[j])
        out[(target.articulation, target.dofs[0])] = LimitRow(
            lower, upper, float(model.jnt_margin[j]), SoftRow.of(model, model.jnt_solref[j], model.jnt_solimp[j]),
            float(model.dof_invweight0[dof]), float(inverse[dof]), float(model.dof_armature[dof]))
    return out
