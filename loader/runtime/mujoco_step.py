"""MuJoCo's own step as the joint forces: `set_ctrl` with `Controller.mujoco_step` on.

The per-step terms rebuild MuJoCo's law piece by piece in Python and leave its implicit part to PhysX's drives.
MuJoCo computes the same law in one forward pass and one integrator call: at SAPIEN's state (the constraint rows'
copy of the model, `rows.py`), with the step's clamped ctrl, activation and applied force, its step ends at the
velocity v1, and PhysX, stepping `qf` explicitly with the same joint-space inertia M and bias c, ends there too when

    qf = M (v1 - v0) / dt + c.

v1 comes from MuJoCo's own integrator (implicit damping, actuator kv, the implicitfast and implicit derivatives),
its constraint force replaced by the rows SAPIEN takes (the contacts PhysX applies left out). A damped DoF keeps its
damping D in its PhysX drive, with v1 as the drive's velocity target: where PhysX's inertia is MuJoCo's the drive
holds no force at v1, and where float32 makes them differ a little the drive holds the joint to v1, where `qf` alone
would let M's error scale the step's velocity change (a light link under a heavy servo, dt D > M). A slide on a
turning link keeps no drive: PhysX's drive measures its velocity short of the centripetal term (`slides.py`). Euler
without implicit damping integrates the solver's acceleration: there `qf` is the forces themselves and the drives
hold nothing. PhysX's limits stand out of the rows' way. PhysX's gravity is off on a fully compensated link, which
MuJoCo's bias keeps: the step adds it back. The law is MuJoCo's wherever SAPIEN's coordinates are
MuJoCo's: every joint a hinge or slide, each SAPIEN DoF one MuJoCo DoF (`eligible` says where it is not, and the
terms run instead) (tests/test_loader_mujoco_step.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from .dof_step import DofLayout, Step
from .drive_forces import DriveForces
from .integrated import accelerated
from .rows import RowTerm, solve
from .term import Handover

EULER, RK4 = int(mujoco.mjtIntegrator.mjINT_EULER), int(mujoco.mjtIntegrator.mjINT_RK4)
INTEGRATORS = {  # RK4 as Euler, as the loader simulates it (listed at load)
    EULER: mujoco.mj_Euler,
    RK4: mujoco.mj_Euler,
    int(mujoco.mjtIntegrator.mjINT_IMPLICIT): mujoco.mj_implicit,
    int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mujoco.mj_implicit,
}
# the terms whose law MuJoCo's step holds in joint space, or that only correct PhysX's drives, which hold nothing here
# (`slides`: a drive's measure on a turning slide); the others act on PhysX in ways a joint force does not
JOINT_SPACE = frozenset({"tendons", "actuators", "stiffness", "rows", "slides", "drives", "fluid", "gravcomp"})


def eligible(model: mujoco.MjModel, rows: RowTerm | None, planned: set[str]) -> str | None:
    """None where MuJoCo's step can give the joint forces, else why not."""
    if rows is None:
        return "no copy of the model for MuJoCo's step (a controller not made by `plan`)"
    if rows.scalar is None:
        return "a joint is not a hinge or slide of its own SAPIEN DoF (a free or ball joint)"
    others = sorted(planned - JOINT_SPACE)
    if others:
        return f"the {', '.join(others)} term acts on PhysX outside the joint forces"
    return None


def unpulled(model: mujoco.MjModel, mapping, layout: DofLayout) -> list[tuple[int, np.ndarray]]:
    """(body, m g) of each body whose link PhysX's gravity does not pull, where MuJoCo's gravity does."""
    gravity = np.asarray(model.opt.gravity, np.float64)
    if mj.disabled(model, "gravity") or not gravity.any():
        return []
    return [
        (body, float(model.body_mass[body]) * gravity)
        for body, target in enumerate(mapping.bodies)
        if body
        and target is not None
        and target.articulation is not None
        and layout.links[target.articulation][target.link].disable_gravity
    ]


class MujocoStep:
    """The joint forces of MuJoCo's own step at SAPIEN's state, solved on the rows' copy (`rows`) and written as
    `qf` by the drive writer (`writer`), whose drives it zeroes."""

    def __init__(self, model: mujoco.MjModel, rows: RowTerm, writer, damping: np.ndarray, layout: DofLayout):
        self.rows, self.writer = rows, writer
        self.integrate = INTEGRATORS[int(model.opt.integrator)]
        # Euler without implicit damping integrates the solver's acceleration, not one solved from the forces
        self.accelerated = accelerated(model)
        self.change, self.force = np.zeros(model.nv), np.zeros(model.nv)
        # per drive DoF, the damping its PhysX drive holds toward v1 (none where MuJoCo integrates the forces)
        self.damping = np.zeros_like(damping) if self.accelerated else damping
        damped = self.damping.nonzero()[0]
        dof_of_flat = np.zeros(layout.size, dtype=int)
        dof_of_flat[rows.scalar] = np.arange(rows.scalar.size)
        self.damped_dofs = dof_of_flat[layout.flat[damped]]  # their MuJoCo DoFs, and their PhysX joints
        self.damped_joints = [layout.joints[i] for i in damped.tolist()]
        self.zeroed = False  # PhysX's drives hold only `damping` (`zero`)
        # the step's record, made by the first `Controller.begin` and renewed by the next: this law writes its whole
        # `force` and reads neither the drive law nor the caller's force in SAPIEN's layout
        self.record: Step | None = None
        self.unpulled = unpulled(model, rows.mapping, layout)
        self.pulled = np.zeros(model.nv)

    def contribute(self, step: Step) -> None:
        rows = self.rows
        if not rows.soft:
            rows.hold(step.joints, soft=True)
        rows.clear_of(step)
        data = rows.data
        with rows.lent as model:
            rows.mirror_state(step)
            solve(model, data, rows.with_contacts, step.timestep, rows.depenetration, not rows.mujocos)
            if self.accelerated:  # Euler integrates the solver's qacc: the forces themselves
                constraint = rows.joint_rows(True)
                force = data.qfrc_passive + data.qfrc_actuator + data.qfrc_applied + constraint
                data.qacc_warmstart[:] = data.qacc
            else:
                if rows.contact_rows:  # left to PhysX
                    data.qfrc_constraint[:] = rows.joint_rows(False)
                force = self.force_to_v1(model, data, step)
            if self.unpulled:
                force += self.gravity_physx_lacks(model, data)
        if force is not step.force:
            step.force[:] = 0.0
            step.force[rows.scalar] = force
        if not self.zeroed:
            self.zero(step.layout.joints)
        if self.damped_joints:
            for joint, velocity in zip(self.damped_joints, data.qvel[self.damped_dofs].tolist()):
                joint.set_drive_velocity_target(velocity)
        self.writer.write_qf(step)

    def gravity_physx_lacks(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The joint forces of the gravity MuJoCo's bias holds and PhysX does not apply: on the links whose gravity
        is off (a body compensated fully, `gravcomp.py`), J^T m g at their centres of mass, with `data` at the step's
        start (tests/test_loader_mujoco_step.py::test_a_compensated_arm_follows_mujoco_under_its_step)."""
        pulled, zero = self.pulled, np.zeros(3)
        pulled[:] = 0.0
        for body, weight in self.unpulled:
            mujoco.mj_applyFT(model, data, weight, zero, data.xipos[body], body, pulled)
        return pulled

    def force_to_v1(self, model: mujoco.MjModel, data: mujoco.MjData, step: Step) -> np.ndarray:
        """M (v1 - v0) / dt + c, into `step.force` where SAPIEN's DoFs are MuJoCo's in order: MuJoCo's integrator
        takes `data` to v1 (and keeps qacc for the next solve's warm start, as mj_step does); M and c stay those of
        the start state, which it leaves as they were."""
        in_order, change = self.rows.in_order, self.change
        start = step.v if in_order else data.qvel.copy()
        self.integrate(model, data)
        np.subtract(data.qvel, start, out=change)
        change *= 1.0 / step.timestep
        force = step.force if in_order else self.force
        mujoco.mj_mulM(model, data, force, change)
        force += data.qfrc_bias
        return force

    def zero(self, joints: list) -> None:
        """PhysX's drives hold only the implicit damping (no stiffness, no target yet); the writer writes every
        setting again when the terms take over."""
        for joint, damping in zip(joints, self.damping.tolist()):
            joint.set_drive_properties(0.0, damping, np.inf if damping else 0.0, "force")
        if self.writer.written is not None:
            self.writer.written[:] = np.nan
        if isinstance(self.writer, DriveForces):
            self.writer.zeroed = True
        self.zeroed = True

    def release(self, handover: Handover) -> None:
        self.zeroed = False
