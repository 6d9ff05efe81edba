"""connect and weld equalities as MuJoCo's soft row on a PhysX D6 joint, rewritten by `set_ctrl` every step:
the connect's three rows on the D6's linear drives, a weld's rotational rows on its slerp drive, the anchor moved
to the pin and the centripetal term the step leaves out put into the target. `release` locks the D6;
`set_active` is MuJoCo's eq_active. Derivation: docs/mapping.md#equalities.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import mujoco
import numpy as np
import sapien

from ..model.equalities import D6Joint, EqualityLink
from ..model.frames import cross, quat_conj, quat_mul
from ..model.soft_row import SoftRow
from .term import Handover, Term

FORCE_LIMIT = 1e30  # no force limit on the D6's drives


def _skew(v) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@dataclass
class _Motion:
    """One end of the D6: pose, centre of mass, its velocity, angular velocity (a static end: its fixed pose)."""

    pose: sapien.Pose
    com: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray

    @classmethod
    def of(cls, link, static_pose: sapien.Pose) -> _Motion:
        if link is None:
            zero = np.zeros(3)
            return cls(static_pose, static_pose.p, zero, zero)
        pose = link.entity_pose
        return cls(
            pose,
            (pose * link.cmass_local_pose).p,
            np.asarray(link.linear_velocity, dtype=float),
            np.asarray(link.angular_velocity, dtype=float),
        )

    def point(self, anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position and velocity of a point fixed in this end (`anchor` in its frame)."""
        point = self.pose.to_transformation_matrix()[:3, :3] @ anchor + self.pose.p
        return point, self.point_velocity(point)

    def point_velocity(self, point: np.ndarray) -> np.ndarray:
        """Velocity of the material point of this end at world position `point`."""
        return self.velocity + cross(self.omega, point - self.com)


@dataclass
class SoftConnect:
    """A connect as MuJoCo's soft rows on the D6's linear drives (`update` before every step).

    `child` and `parent` are the D6's ends (None: the world or a body of the static actor, at `parent_pose`),
    `child_anchor` / `parent_anchor` MuJoCo's anchor of each in its body frame, `frame` the parent's D6 frame
    rotation in its body frame. Everything is in child-minus-parent terms, MuJoCo's residual r = p1 - p2 when the
    child is body1 and -r otherwise: the law is odd in r and v, so it holds either way."""

    drive: sapien.physx.PhysxDriveComponent
    child: sapien.physx.PhysxArticulationLinkComponent
    child_anchor: np.ndarray
    parent: sapien.physx.PhysxArticulationLinkComponent | None
    parent_anchor: np.ndarray
    parent_pose: sapien.Pose  # the static parent's world pose (identity for the world)
    frame: sapien.Pose
    row: SoftRow
    diag_approx: np.ndarray  # MuJoCo's diagApprox per row (3 for a connect, 6 for a weld)
    equality: int  # MuJoCo's equality id
    child_body: int  # MuJoCo body ids of the ends
    parent_body: int
    articulation: int | None  # the child's articulation
    child_rotation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))  # D6 frame in child
    active: bool = True  # MuJoCo's eq_active
    soft: bool = False  # the D6 is free and driven (False: locked by `lock`, or free and idle when inactive)

    def update(self, timestep: float) -> None:
        """MuJoCo's soft law for the coming step, from the current state."""
        if not self.active:
            return
        child, parent = _Motion.of(self.child, sapien.Pose()), _Motion.of(self.parent, self.parent_pose)
        child_point, child_velocity = child.point(self.child_anchor)
        parent_point, parent_velocity = parent.point(self.parent_anchor)
        residual, velocity = child_point - parent_point, child_velocity - parent_velocity
        imp = self.row.impedance(
            float(np.linalg.norm(np.concatenate([residual, self.rotation_residual(child, parent)])))
        )
        damping = 1.0 / (timestep * self.row.regularizer(imp, self.diag_approx[0]))
        pin = self.pin(child_point, parent_point)
        if self.parent is not None:  # the D6's anchor follows the pin, fixed in the child for the step
            self.drive.set_pose_in_child(sapien.Pose((child.pose.inv() * sapien.Pose(pin)).p, self.child_rotation))
        target = self.measured(child, parent, pin) + timestep * (
            self.row.reference(imp, residual, velocity) - self.centripetal(child, parent, pin)
        )
        rotation = (parent.pose * self.frame).to_transformation_matrix()[:3, :3]
        self._free()
        self._drive(damping, rotation.T @ target, self.angular_target(child, parent, imp, timestep, rotation))

    def rotation_residual(self, child: _Motion, parent: _Motion) -> np.ndarray:
        return np.zeros(0)

    def angular_target(self, child, parent, imp, timestep, rotation) -> np.ndarray:
        return np.zeros(3)

    def pin(self, child_point: np.ndarray, parent_point: np.ndarray) -> np.ndarray:
        """Where the D6 acts: PhysX applies both ends' forces at the child's anchor, MuJoCo each body's at its own.
        Against a body that does not move, the child's anchor is exact; between two moving bodies the midpoint
        cancels the first-order error at rest
        (tests/test_loader_connect.py::test_taking_both_ends_at_the_pin_matters_for_an_open_moving_loop)."""
        return child_point if self.parent is None else 0.5 * (child_point + parent_point)

    @staticmethod
    def measured(child: _Motion, parent: _Motion, pin: np.ndarray) -> np.ndarray:
        """The row velocity the D6 sees: both ends at the pin (MuJoCo's takes each body at its own anchor)."""
        return child.point_velocity(pin) - parent.point_velocity(pin)

    @staticmethod
    def centripetal(child: _Motion, parent: _Motion, pin: np.ndarray) -> np.ndarray:
        """What PhysX's step leaves out of the row's velocity change: w x (w x r) of the pin about each end's
        centre of mass."""
        return cross(child.omega, cross(child.omega, pin - child.com)) - cross(
            parent.omega, cross(parent.omega, pin - parent.com)
        )

    def _free(self) -> None:
        if not self.soft:
            for axis in "xyz":
                getattr(self.drive, f"set_limit_{axis}")(-np.inf, np.inf)
            self.soft = True

    def _drive(self, damping: float, linear: np.ndarray, angular: np.ndarray) -> None:
        """The linear drives' damping (no stiffness) and the velocity targets."""
        for axis in "xyz":
            getattr(self.drive, f"set_drive_property_{axis}")(0.0, damping, FORCE_LIMIT, "force")
        self.drive.set_drive_velocity_target(linear, angular)

    def _idle(self) -> None:
        """Free and undriven: MuJoCo's inactive equality."""
        self._free()
        self._drive(0.0, np.zeros(3), np.zeros(3))

    def stand_by(self) -> None:
        """Free and undriven while MuJoCo's own rows hold the loop (`runtime/rows.py`); `lock` takes over at
        `release()`."""
        self._idle()

    def set_active(self, active: bool) -> None:
        """MuJoCo's `data.eq_active`: an inactive equality leaves the D6 free and undriven."""
        self.active = bool(active)
        if not self.active:
            self._idle()

    def lock(self, timestep: float) -> None:
        """For callers that stop calling `update` (`release`): locked translation, no drive; or free if inactive."""
        if not self.active:
            self._idle()
            return
        for axis in "xyz":
            getattr(self.drive, f"set_limit_{axis}")(0.0, 0.0)
        self._drive(0.0, np.zeros(3), np.zeros(3))
        self.soft = False


@dataclass
class SoftWeld(SoftConnect):
    """A weld: the connect's linear rows at its anchor plus MuJoCo's three rotational rows on the slerp drive."""

    relative_quat: np.ndarray = None  # MuJoCo's relpose rotation (body2 in body1's frame)
    torquescale: float = 1.0
    child_is_body1: bool = False

    def _bodies(self, child: _Motion, parent: _Motion) -> tuple[_Motion, _Motion]:
        return (child, parent) if self.child_is_body1 else (parent, child)

    def _error(self, child: _Motion, parent: _Motion) -> np.ndarray:
        """e = conj(q2) q1 relquat: MuJoCo's rotational residual is torquescale times its vector part."""
        body1, body2 = self._bodies(child, parent)
        return quat_mul(quat_conj(np.asarray(body2.pose.q)), quat_mul(np.asarray(body1.pose.q), self.relative_quat))

    def rotation_residual(self, child: _Motion, parent: _Motion) -> np.ndarray:
        return self.torquescale * self._error(child, parent)[1:]

    def angular_target(self, child, parent, imp, timestep, rotation) -> np.ndarray:
        scale = self.torquescale
        if scale == 0:
            self.drive.set_drive_property_slerp(0.0, 0.0, FORCE_LIMIT, "force")
            return np.zeros(3)
        body1, body2 = self._bodies(child, parent)
        e = self._error(child, parent)
        body2_rotation = body2.pose.to_transformation_matrix()[:3, :3]
        relative = body1.omega - body2.omega
        omega = body2_rotation.T @ relative  # body1 relative to body2, in body2's frame
        gain = 0.5 * scale * (e[0] * np.eye(3) - _skew(e[1:]))
        row_velocity = gain @ omega
        reference = self.row.reference(imp, scale * e[1:], row_velocity) - self.frame_rate(
            scale, e, gain, omega, body2_rotation, body2.omega, relative
        )
        row_damping = 1.0 / (timestep * self.row.regularizer(imp, self.diag_approx[3]))
        self.drive.set_drive_property_slerp(0.0, 0.25 * scale * scale * row_damping, FORCE_LIMIT, "force")
        sign = 1.0 if self.child_is_body1 else -1.0
        return (
            sign
            * (4.0 / (scale * scale))
            * (rotation.T @ body2_rotation @ gain.T @ (row_velocity + timestep * reference))
        )

    @staticmethod
    def frame_rate(scale, e, gain, omega, body2_rotation, body2_omega, relative) -> np.ndarray:
        """The part of the rotational rows' J' qdot that PhysX's step does not carry: the rates of G and of R2^T
        (the links' own angular velocity-product terms it carries)."""
        e_rate = 0.5 * quat_mul(np.concatenate([[0.0], omega]), e)
        gain_rate = 0.5 * scale * (e_rate[0] * np.eye(3) - _skew(e_rate[1:]))
        return gain_rate @ omega - gain @ (body2_rotation.T @ cross(body2_omega, relative))

    def _idle(self) -> None:
        super()._idle()
        self.drive.set_drive_property_slerp(0.0, 0.0, FORCE_LIMIT, "force")

    def lock(self, timestep: float) -> None:
        """For callers that stop calling `update`: translation locked, rotation held by the slerp drive (PhysX's D6
        locks only twist, not swing) as a spring-damper: the closed loop's damper, and a spring that closes an
        opening at MuJoCo's reference rate K imp / B. Approximate
        (tests/test_loader_connect.py::test_after_release_a_weld_keeps_its_relative_rotation)."""
        super().lock(timestep)
        if not self.active or self.torquescale == 0:
            return
        imp = self.row.impedance(0.0)
        damping = 0.25 * self.torquescale**2 / (timestep * self.row.regularizer(imp, self.diag_approx[3]))
        self.drive.set_drive_target(sapien.Pose())
        self.drive.set_drive_property_slerp(
            damping * self.row.stiffness * imp / self.row.damping, damping, FORCE_LIMIT, "force"
        )


@dataclass
class EqualityTerm(Term):
    """The soft connect and weld equalities, updated once per `set_ctrl` after the joints' drives are written."""

    connects: list[SoftConnect]

    name = "equalities"

    def contribute(self, step) -> None:
        for connect in self.connects:
            connect.update(step.timestep)

    def release(self, handover: Handover) -> None:
        for connect in self.connects:
            connect.lock(handover.timestep)

    def velocity_links(self, articulations) -> list:
        return [end for c in self.connects for end in (c.child, c.parent) if end is not None]


def soft_law(model: mujoco.MjModel, joint: D6Joint, timestep: float) -> SoftConnect:
    """The per-step law of a D6 joint the load built, with MuJoCo's soft row of `model` (solref, solimp) at
    `timestep`; locked rigid until the first `set_ctrl`, and idle where the equality starts inactive."""
    kind = SoftWeld if joint.weld else SoftConnect
    given = {f.name: getattr(joint, f.name) for f in fields(kind) if f.init and hasattr(joint, f.name)}
    e = joint.equality
    given["row"] = SoftRow.of(model, model.eq_solref[e], model.eq_solimp[e], timestep)
    law = kind(**given)
    law.lock(timestep)
    if not model.eq_active0[e]:
        law.set_active(False)
    return law


def plan_equalities(model: mujoco.MjModel, links: list[EqualityLink], timestep: float) -> dict[int, SoftConnect]:
    """Per equality id, the soft law of each D6 joint the load built: a D6 joint's own, or one standing by beside
    MuJoCo's rows (`runtime/rows.py`) for `release()`."""
    return {link.index: soft_law(model, link.joint, timestep) for link in links if link.joint is not None}
