"""The drive law as joint forces, for PhysX's TGS solver.

Under PGS a PhysX drive's implicit law lands on MuJoCo's step (`drive_writer.py`). TGS solves drives over its
position iterations, each a fraction of the step, and lands elsewhere; a joint force (`qf`) it steps as PGS does.
So under TGS every drive DoF's law, as the drive would hold it (F(v1) = a - d v1, with a = K (target - q0) + D' vt
and d = K dt + D' from the same targets and gains), is solved here, coupled through MuJoCo's joint-space inertia M
at SAPIEN's state:

    (M + dt diag(d)) (v1 - v0) = dt (f + a - d v0 - c)

with f the generalized force the terms gathered and c MuJoCo's bias (Coriolis and gravity) less the gravity
compensation and fluid forces, which their own terms add to the links. Each drive's force a - d v1 joins f in `qf`,
and PhysX's drives hold nothing. A drive whose force passes its limit (a law edited with one) holds the limit. A
slide on a turning link needs no offset here: the force is not PhysX's drive measure
(tests/test_loader_solver.py::test_under_tgs_the_drives_are_written_as_forces_and_follow_mujoco).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model.drive import DofDrive
from ..model.mapping import Mapping
from .dof_step import DofKey, Step
from .drive_writer import DriveWriter
from .term import Compilation, Handover, Term


class DriveForces(DriveWriter):
    """`DriveWriter`'s law, written as joint forces solved with MuJoCo's M (the `drives` stage under TGS)."""

    def __init__(self, passive: dict[DofKey, DofDrive], model: mujoco.MjModel, mapping: Mapping):
        super().__init__(passive)
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.inertia_matrix = np.zeros((model.nv, model.nv))
        self.link_forces = bool(np.any(model.body_gravcomp)) or model.opt.density > 0 or model.opt.viscosity > 0
        self.zeroed = False  # PhysX's drives hold nothing

    def compile(self, compilation: Compilation) -> None:
        super().compile(compilation)
        self.offsets = False
        dofs, layout = self.mapping.mujoco_dofs(), compilation.layout
        self.dof_of_flat = np.full(layout.size, -1, dtype=int)
        for (a, d), dof in dofs.items():
            self.dof_of_flat[layout.starts[a] + d] = dof
        self.dof_of_drive = self.dof_of_flat[layout.flat]
        known = self.dof_of_flat >= 0  # each a DoF of its own: one joint position per MuJoCo DoF
        self.known_flat, self.known_dofs = known.nonzero()[0], self.dof_of_flat[known]
        self.zeroed = False

    def contribute(self, step: Step) -> None:
        regime, target, velocity_target = self.split(step)
        flat, timestep = self.layout.flat, step.timestep
        stiffness, damping = regime.stiffness, regime.damping
        law = stiffness * (target - step.q[flat]) + damping * velocity_target  # a
        implicit = stiffness * timestep + damping  # d
        step.force[flat] += self.solve(step, law, implicit, regime.force_limit)
        if not self.zeroed:
            for joint in self.layout.joints:
                joint.set_drive_properties(0.0, 0.0, 0.0, "force")
            self.written[:] = np.nan
            self.zeroed = True
        self.write_qf(step)

    def batch(self, step: Step, steps: list[Step], terms: list[Term]) -> bool:
        """Never for every copy at once: each copy's drive law is solved with its own M at its own state
        (tests/test_loader_batch.py::test_a_batch_under_tgs_steps_each_copy_as_its_own_set_ctrl)."""
        return False

    def solve(self, step: Step, law: np.ndarray, implicit: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """Each drive's force a - d v1 at the end of the step, held within its force limit (a limit that binds
        leaves the others as solved with it free)."""
        qvel, inertia, bias = self.dynamics(step)
        total = -bias
        total[self.known_dofs] += step.force[self.known_flat]
        drives, timestep = self.dof_of_drive, step.timestep
        v0 = qvel[drives]
        total[drives] += law - implicit * v0
        inertia[drives, drives] += timestep * implicit
        v1 = v0 + timestep * np.linalg.solve(inertia, total)[drives]
        return np.clip(law - implicit * v1, -limit, limit)

    def dynamics(self, step: Step) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """MuJoCo's qvel, M (armature included) and bias at the step's state, the bias less gravity compensation
        and fluid: read from the forward pass the rows ran at this state (`Step.forwarded`), else from this term's
        own passes (tests/test_loader_solver.py::test_under_tgs_the_drives_read_the_rows_forward_pass)."""
        model, data = self.model, step.forwarded
        if data is None:
            data = self.data
            data.qpos[:], data.qvel[:] = step.mujoco_state(self.mapping)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_crb(model, data)
            mujoco.mj_comVel(model, data)
            mujoco.mj_rne(model, data, 0, data.qfrc_bias)
            if self.link_forces:
                mujoco.mj_tendon(model, data)
                mujoco.mj_passive(model, data)
        bias = data.qfrc_bias - (data.qfrc_gravcomp + data.qfrc_fluid) if self.link_forces else data.qfrc_bias
        mujoco.mj_fullM(model, data, self.inertia_matrix)
        return data.qvel, self.inertia_matrix, bias

    def release(self, handover: Handover) -> None:
        super().release(handover)
        self.zeroed = False
