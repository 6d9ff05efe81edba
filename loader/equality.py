"""Equality constraints: joint and tendon couplings as stiff PhysX fixed tendons, connect and weld as PhysX D6
joints.

MuJoCo's equalities are soft: solref (timeconst, dampratio) gives a reference acceleration -b v - k r with
k = 1 / (dmax^2 timeconst^2 dampratio^2) and b = 2 / (dmax timeconst), and the impedance d (solimp) mixes it
with the unconstrained acceleration a0: the constraint accelerates as (1 - d) a0 + d (-b v - k r). A spring and
damper on the constraint's effective mass m = 1 / (J M^-1 J^T) behave the same when their gains are
m d / (1 - d) times k and b. The loader takes m at qpos0 and d at small violations (solimp's dmin).
That equivalence is approximate: a spring-damper does not take up the unconstrained acceleration a0 the way
MuJoCo's constraint does (measured 4.4e-3 rad over 2 s on the coupled-joint fixture). An exact form exists (a
tendon damping 1 / (dt R) with R MuJoCo's regularizer, stiffness K d / R, and an explicit force
(1/dt - B) / R x rate every step), but it needs PhysX's iterative tendon solve to converge at strong gains: on
dm_control manipulator it reaches one-step 4.5e-6 rad/s only at 200 position iterations, and with coupling
ratio 2 (the fixture) PhysX's tendon solve diverges (`tendon.py`). Not used.

A connect takes that exact form on a PhysX D6 joint, whose three linear drive rows PhysX solves one constraint row
each (`impedance.py`): damping D = 1 / (dt R) and a velocity target, rewritten by `set_ctrl` before every step
(`SoftConnect`). Two PhysX details enter the target, both measured on a four-bar and a two-link loop: the D6
measures the parent's velocity at the child's anchor, and PhysX's step leaves the row's velocity short of the
centripetal term w x (w x r) of each anchor about its link's centre of mass (r from it). With them the first step
matches MuJoCo to float32 (2e-7 rad/s at joint speeds up to 4 rad/s, with the world as parent also on an open
loop); MuJoCo's velocity-product term J' qdot is then not needed. Left: between two moving links the D6 takes both
ends at the child's anchor where MuJoCo takes each body at its own, an error first order in the loop's violation
(9.5e-6 rad/s at rest with the loop open by 3.6e-5 m, corpus/fixtures/closed_chain.xml); and MuJoCo solves the
constraint with M and integrates joint damping with M + dt D afterwards, PhysX solves both together (5e-5 rad/s on
a four-bar with 0.01 damping on its crank, 1.9e-2 on the 2f85's linkage).
`release` locks the D6 again (its callers do not rewrite the target); the next `set_ctrl` frees it.
A weld stays rigid: its translational rows take the connect's form, but for its rotational rows (MuJoCo's
ts imag(conj(q2) q1 relquat), row velocity ts/2 (e_w I - [e_v]x) R2^T (w1 - w2)) no PhysX slerp-drive target was
found that makes the first step exact (1e-3 rad/s at 1 rad/s on a two-leg fixture, with MuJoCo's aref).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import sapien

from .errors import Notes
from .frames import cross
from .impedance import SoftRow, diag_approx
from .mapping import Mapping
from .tendon import create_fixed_tendon, fixed_tendon_terms
from .tree import forward_at_qpos0, world_poses_at_qpos0

EQ = mujoco.mjtEq


@dataclass
class EqualityLink:
    """What an equality constraint became: a fixed tendon or a D6 joint (`kind`), or nothing (`mapped` False)."""

    name: str
    kind: str
    mapped: bool
    reason: str = ""
    soft: SoftConnect | None = None  # a connect's per-step soft law (None: rigid or not a connect)


FORCE_LIMIT = 1e30  # no force limit on the D6 damper


@dataclass
class SoftConnect:
    """A connect as MuJoCo's soft row on a free D6 joint: damping 1 / (dt R) and a velocity target per step.

    `child` and `parent` are the D6's ends (parent None: the world), `child_anchor` / `parent_anchor` the anchor in
    each end's link frame (the parent's in world coordinates when it is the world), `frame` the parent's D6 frame
    rotation in its link frame. Everything is in child-minus-parent terms: MuJoCo's residual r = p1 - p2 when the
    child is body1, its negative otherwise (the law is odd in r and v, so it holds either way)."""

    drive: sapien.physx.PhysxDriveComponent
    child: sapien.physx.PhysxArticulationLinkComponent
    child_anchor: np.ndarray
    parent: sapien.physx.PhysxArticulationLinkComponent | None
    parent_anchor: np.ndarray
    frame: sapien.Pose
    row: SoftRow
    diag_approx: float
    equality: int  # MuJoCo's equality id
    articulation: int | None  # the child's articulation (solver iterations, `solver.py`)
    soft: bool = False  # the locks are released (set by the first `update`)

    @staticmethod
    def _motion(link) -> tuple[sapien.Pose, np.ndarray, np.ndarray, np.ndarray]:
        """The link's pose, centre of mass, its velocity and the angular velocity (the world: at rest)."""
        if link is None:
            zero = np.zeros(3)
            return sapien.Pose(), zero, zero, zero
        pose = link.entity_pose
        return (pose, (pose * link.cmass_local_pose).p, np.asarray(link.linear_velocity, dtype=float),
                np.asarray(link.angular_velocity, dtype=float))

    def update(self, timestep: float) -> None:
        """MuJoCo's soft law for the coming step, from the current state."""
        child_pose, child_com, child_com_velocity, child_omega = self._motion(self.child)
        parent_pose, parent_com, parent_com_velocity, parent_omega = self._motion(self.parent)
        child = child_pose.to_transformation_matrix()[:3, :3] @ self.child_anchor + child_pose.p
        parent = parent_pose.to_transformation_matrix()[:3, :3] @ self.parent_anchor + parent_pose.p
        residual = child - parent
        child_velocity = child_com_velocity + cross(child_omega, child - child_com)
        parent_velocity = parent_com_velocity + cross(parent_omega, parent - parent_com)
        velocity = child_velocity - parent_velocity
        imp = self.row.impedance(float(np.linalg.norm(residual)))
        damping = 1.0 / (timestep * self.row.regularizer(imp, self.diag_approx))
        target = (self.measured(velocity, parent_omega, residual)
                  + timestep * (self.row.reference(imp, residual, velocity)
                                - self.centripetal(child, child_com, child_omega, parent_com, parent_omega)))
        rotation = (parent_pose * self.frame).to_transformation_matrix()[:3, :3]
        if not self.soft:
            for axis in "xyz":
                getattr(self.drive, f"set_limit_{axis}")(-np.inf, np.inf)
            self.soft = True
        for axis in "xyz":
            getattr(self.drive, f"set_drive_property_{axis}")(0.0, damping, FORCE_LIMIT, "force")
        self.drive.set_drive_velocity_target(rotation.T @ target, np.zeros(3))

    @staticmethod
    def measured(velocity, parent_omega, residual) -> np.ndarray:
        """The row velocity the D6 sees: MuJoCo's takes each body at its own anchor, PhysX the parent at the
        child's anchor, which lies `residual` away."""
        return velocity - cross(parent_omega, residual)

    @staticmethod
    def centripetal(child, child_com, child_omega, parent_com, parent_omega) -> np.ndarray:
        """What PhysX's step leaves out of the row's velocity change: w x (w x r) of the child's anchor about
        each end's centre of mass."""
        return (cross(child_omega, cross(child_omega, child - child_com))
                - cross(parent_omega, cross(parent_omega, child - parent_com)))

    def lock(self) -> None:
        """Back to the rigid form (locked translation, no drive), for callers that stop calling `update`."""
        for axis in "xyz":
            getattr(self.drive, f"set_limit_{axis}")(0.0, 0.0)
            getattr(self.drive, f"set_drive_property_{axis}")(0.0, 0.0, FORCE_LIMIT, "force")
        self.drive.set_drive_velocity_target(np.zeros(3), np.zeros(3))
        self.soft = False


def _name(model: mujoco.MjModel, e: int) -> str:
    return model.equality(e).name or f"equality{e}"


def soft_gains(model: mujoco.MjModel, e: int, jacobian: np.ndarray, data: mujoco.MjData) -> tuple[float, float]:
    """Spring and damper (force per unit violation / rate) of equality `e` along `jacobian` at qpos0 (`data`: MuJoCo's
    forward pass there): MuJoCo's K and B (`impedance.SoftRow`) times m d / (1 - d), m the effective mass."""
    row = SoftRow.of(model, model.eq_solref[e], model.eq_solimp[e])
    dmin = row.impedance(0.0)
    solved = np.zeros((1, model.nv))
    mujoco.mj_solveM(model, data, solved, jacobian.reshape(1, -1))
    mass = 1.0 / float(jacobian @ solved[0])
    scale = mass * dmin / (1.0 - dmin)
    return row.stiffness * scale, row.damping * scale


def _joint_dof(model: mujoco.MjModel, mapping: Mapping, joint: int) -> tuple[int, int] | None:
    target = mapping.joints[joint]
    if target.kind not in ("hinge", "slide"):
        return None
    return target.articulation, target.dofs[0]


def map_equalities(model: mujoco.MjModel, scene: sapien.Scene, articulations, mapping: Mapping,
                   notes: Notes) -> list[EqualityLink]:
    result = []
    if model.opt.disableflags & (mujoco.mjtDisableBit.mjDSBL_EQUALITY | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT):
        return result  # MuJoCo enforces none of them (<flag equality/constraint="disable"/>)
    at_qpos0 = []  # MuJoCo's forward pass at qpos0, made once (effective masses, diagApprox)

    def qpos0_data() -> mujoco.MjData:
        if not at_qpos0:
            at_qpos0.append(forward_at_qpos0(model))
        return at_qpos0[0]

    for e in range(model.neq):
        name = _name(model, e)
        etype = int(model.eq_type[e])
        if not model.eq_active0[e]:
            notes.drop("equality", name, "inactive at start: PhysX constraints cannot be switched on later")
            result.append(EqualityLink(name, "", False, "inactive"))
            continue
        if etype in (int(EQ.mjEQ_JOINT), int(EQ.mjEQ_TENDON)):
            result.append(_coupling(model, e, name, articulations, mapping, notes, qpos0_data))
        elif etype in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
            result.append(_d6(model, e, name, scene, articulations, mapping, notes, qpos0_data))
        else:
            reason = f"equality type {EQ(etype).name.removeprefix('mjEQ_').lower()} has no PhysX equivalent"
            notes.drop("equality", name, reason)
            result.append(EqualityLink(name, "", False, reason))
    return result


def _coupling(model, e, name, articulations, mapping, notes, qpos0_data) -> EqualityLink:
    """obj1 = poly(obj2): the linear part, obj1 - c1 obj2 = c0, as a fixed tendon over the joints involved."""
    c0, c1, *higher = model.eq_data[e][:5]
    if any(abs(c) > 0 for c in higher):
        notes.approximate("equality", name, "polynomial coupling: only its linear part (c0 + c1 x) is mapped")
    etype = int(model.eq_type[e])
    objects = [int(model.eq_obj1id[e])] + ([int(model.eq_obj2id[e])] if model.eq_obj2id[e] >= 0 else [])
    weights = [1.0, -float(c1)]
    terms: dict[tuple[int, int], float] = {}
    for obj, weight in zip(objects, weights):
        joints = [(obj, 1.0)] if etype == int(EQ.mjEQ_JOINT) else fixed_tendon_terms(model, obj)
        if not joints:
            reason = "couples a spatial tendon, which PhysX cannot express"
            notes.drop("equality", name, reason)
            return EqualityLink(name, "", False, reason)
        for joint, coefficient in joints:
            dof = _joint_dof(model, mapping, joint)
            if dof is None:
                reason = "couples a ball or free joint"
                notes.drop("equality", name, reason)
                return EqualityLink(name, "", False, reason)
            terms[dof] = terms.get(dof, 0.0) + weight * coefficient
    if len({a for a, _ in terms}) != 1:
        reason = "couples joints of two articulations"
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason)
    # MuJoCo couples displacements from qpos0 (tendon_length0): y - y0 = c0 + c1 (x - x0), x absent for one object
    if etype == int(EQ.mjEQ_JOINT):
        reference = [float(model.qpos0[model.jnt_qposadr[obj]]) for obj in objects]
    else:
        reference = [float(model.tendon_length0[obj]) for obj in objects]
    offset = float(c0) + reference[0] - (float(c1) * reference[1] if len(objects) > 1 else 0.0)
    mujoco_dof = {target: i for i, target in enumerate(mapping.dofs)}
    jacobian = np.zeros(model.nv)
    for key, coefficient in terms.items():
        jacobian[mujoco_dof[key]] = coefficient
    stiffness, damping = soft_gains(model, e, jacobian, qpos0_data())
    articulation = next(iter(terms))[0]
    # the gains go to PhysX as they are, so PhysX spreads them over the tendon's joints (tendon.py): measured
    # closer to MuJoCo than the whole gains (times the joint count) on the coupled-joint fixture (4.4e-3 against
    # 1.5e-2 rad) and on dm_control manipulator (one-step qacc 2.6e-2 against 6.8e-2), further on the panda's
    # fingers (6.7e-2 against 1.9e-2): a spring cannot reproduce MuJoCo's impedance either way
    create_fixed_tendon(articulations[articulation], {d: c for (_, d), c in terms.items()}, offset,
                        stiffness, damping)
    notes.approximate("equality", name, "solref softness mapped to tendon stiffness/damping at qpos0's "
                      "effective mass")
    return EqualityLink(name, "fixed tendon", True)


def _d6(model, e, name, scene, articulations, mapping, notes, qpos0_data) -> EqualityLink:
    """connect: the two anchor points coincide (translation locked); weld: the relative pose is held too."""
    if int(model.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
        reason = "site-based connect/weld is not mapped"
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason)
    body1, body2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])

    def component(body):
        target = mapping.bodies[body]
        if target.articulation is None:
            return None
        return articulations[target.articulation].links[target.link]

    etype = int(model.eq_type[e])
    if etype == int(EQ.mjEQ_CONNECT):
        frame1 = sapien.Pose(model.eq_data[e][0:3])  # the anchor in body1's frame
        frame2 = sapien.Pose(model.eq_data[e][3:6])  # the same point in body2's frame at qpos0
    else:
        # weld: body2 held at `relpose` in body1's frame (the qpos0 relative pose when relpose is unset)
        relative_quat = model.eq_data[e][6:10]
        if np.linalg.norm(relative_quat) > 0:
            frame1 = sapien.Pose(model.eq_data[e][3:6], relative_quat / np.linalg.norm(relative_quat))
        else:
            data = world_poses_at_qpos0(model)
            frame1 = (sapien.Pose(data.xpos[body1], data.xquat[body1]).inv()
                      * sapien.Pose(data.xpos[body2], data.xquat[body2]))
        frame2 = sapien.Pose()
    world = world_poses_at_qpos0(model)

    def end(body, frame):  # a body of the static actor is the world: its frame in world coordinates
        link = component(body)
        if link is None:
            frame = sapien.Pose(world.xpos[body], world.xquat[body]) * frame
        return link, frame, body

    ends = [end(body1, frame1), end(body2, frame2)]
    rows = diag_approx(model, qpos0_data(), int(mujoco.mjtConstraint.mjCNSTR_EQUALITY), e)
    if not len(rows) or (ends[0][0] is None and ends[1][0] is None):  # MuJoCo makes no rows for it
        reason = "joins two bodies fixed to the world: it constrains no degree of freedom"
        notes.drop("equality", name, reason)
        return EqualityLink(name, "", False, reason)
    if ends[1][0] is None:  # SAPIEN takes the world (None) only as the first end
        ends.reverse()
    (parent, parent_frame, _), (child, child_frame, child_body) = ends
    drive = scene.create_drive(parent, parent_frame, child, child_frame)
    for axis in "xyz":
        getattr(drive, f"set_limit_{axis}")(0.0, 0.0)
    if etype == int(EQ.mjEQ_WELD):
        drive.set_limit_twist(0.0, 0.0)
        drive.set_limit_cone(0.0, 0.0)
        notes.approximate("equality", name, "weld as a rigid PhysX D6 joint (MuJoCo's is soft: solref)")
        return EqualityLink(name, "D6 joint", True)
    soft = SoftConnect(drive, child, np.asarray(child_frame.p, dtype=float), parent,
                       np.asarray(parent_frame.p, dtype=float), sapien.Pose(q=parent_frame.q),
                       SoftRow.of(model, model.eq_solref[e], model.eq_solimp[e]), float(rows[0]), e,
                       mapping.bodies[child_body].articulation)
    notes.approximate("equality", name, "connect as MuJoCo's soft law (solref, solimp) on a PhysX D6 damper that "
                      "set_ctrl updates every step (rigid after release); exact but for the "
                      "coupling with implicit joint damping (equality.py)")
    return EqualityLink(name, "D6 joint", True, soft=soft)
