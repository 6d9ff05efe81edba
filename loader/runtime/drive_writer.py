"""The end of every step's stages: each DoF's law written to its PhysX joint drive (only the settings that
changed), the generalized forces gathered by the terms written with `set_qf`.

A DoF whose implicit drive damping outweighs its inertia over one step (dt D > M_ii, MuJoCo's joint-space inertia
at qpos0 with armature) takes its gathered force through the drive's velocity target instead: PhysX adds `qf`
explicitly (dt F / M_ii) before the implicit damping takes nearly all of it back, and float32 loses the difference;
in the target the force is solved with the damping. A drive with a force limit keeps `qf` (the limit must not clamp
it). Tested by tests/test_loader_limit.py::test_a_limit_force_on_a_light_damped_link_goes_through_the_drive."""

from __future__ import annotations

import numpy as np

from .. import drive
from ..drive import DofDrive
from .dof_step import DofKey, DofLayout, Step


class DriveWriter:
    """Writes drives and `qf`: each drive DoF's law (`drive.apply`, as arrays), the PhysX calls only for the joints
    whose settings changed since the last write (`written`: stiffness, damping, force limit, target and velocity
    target as last written; NaN: unknown, written next step)."""

    name = "drives"

    def __init__(self, passive: dict[DofKey, DofDrive], inertia: dict[DofKey, float] | None = None):
        self.passive = passive
        self.inertia = {} if inertia is None else inertia  # M_ii at qpos0 (`dof_inertia`); absent: qf only

    def compile(self, layout: DofLayout, offsets: bool = True) -> None:
        """`offsets`: whether any drive carries a velocity offset (`slides.py`); without, adding it is skipped."""
        self.layout, self.offsets = layout, offsets
        self.mass = np.array([self.inertia.get(key, np.inf) for key in layout.keys], dtype=np.float64)
        self.zeros = np.zeros(len(layout.keys))
        self.written = np.full((5, len(layout.keys)), np.nan)

    def contribute(self, step: Step) -> None:
        """`drive.apply` on every drive DoF at once: the position target carries the constant where the drive has
        stiffness, the velocity target what is left where it has damping, `qf` the rest."""
        law, force, timestep, flat = step.law, step.force, step.timestep, self.layout.flat
        stiffness, constant, via_damping, offset = law[0], law[2], law[4], law[6]
        damping = law[1] + law[5]
        damping -= stiffness * timestep
        np.maximum(damping, 0.0, out=damping)  # `DofDrive.physx_damping`
        heavy = ((timestep * damping > self.mass) & (law[3] == np.inf)).nonzero()[0]
        if heavy.size:
            via_damping[heavy] += force[flat[heavy]]
            force[flat[heavy]] = 0.0
        stiff = stiffness > 0
        target = np.divide(constant, stiffness, out=self.zeros.copy(), where=stiff)
        if self.offsets:
            np.add(target, offset * timestep, out=target, where=stiff)
        constant[stiff] = 0.0
        constant += via_damping  # what is left after the position target
        damped = damping > 0
        velocity_target = np.divide(constant, damping, out=self.zeros.copy(), where=damped)
        if self.offsets:
            np.add(velocity_target, offset, out=velocity_target, where=damped)
        constant[damped] = 0.0
        force[flat] += constant
        self.write(np.array([stiffness, damping, law[3], target, velocity_target]))
        for articulation, qf in zip(step.articulations, step.layout.split(force)):
            if articulation.dof:
                articulation.set_qf(qf.astype(np.float32))

    def write(self, settings: np.ndarray) -> None:
        """The PhysX calls for the settings (rows as `written`) that differ from the last ones written."""
        changed = settings != self.written
        self.written = settings
        if not np.count_nonzero(changed):
            return
        joints = self.layout.joints
        for i in (changed[0] | changed[1] | changed[2]).nonzero()[0].tolist():
            joints[i].set_drive_properties(float(settings[0, i]), float(settings[1, i]), float(settings[2, i]),
                                           "force")
        for i in changed[3].nonzero()[0].tolist():
            joints[i].set_drive_target(float(settings[3, i]))
        for i in changed[4].nonzero()[0].tolist():
            joints[i].set_drive_velocity_target(float(settings[4, i]))

    def release(self, joints, articulations, timestep: float) -> None:
        """Every DoF's passive spring-damper in its drive, `qf` cleared."""
        for (art, dof), passive in self.passive.items():
            drive.apply(joints[art][dof], passive, passive.constant, timestep)
        for articulation in articulations:
            if articulation.dof:
                articulation.set_qf(np.zeros(articulation.dof, np.float32))
        if hasattr(self, "written"):
            self.written[:] = np.nan


def dof_inertia(model, mapping) -> dict[DofKey, float]:
    """MuJoCo's joint-space inertia diagonal (armature included) at qpos0, per hinge/slide DoF."""
    from .. import mj

    data = mj.forward_at(model)
    diagonal = data.M[model.M_rowadr + model.M_rownnz - 1]  # a row of the sparse lower triangle ends on its diagonal
    return {key: float(diagonal[d]) for key, d in mapping.mujoco_dofs().items()}
