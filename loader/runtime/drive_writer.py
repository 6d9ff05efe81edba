"""The end of every step's stages: each DoF's law written to its PhysX joint drive (only the settings that
changed), the generalized forces gathered by the terms written with `set_qf`.

A DoF whose implicit drive damping outweighs its inertia over one step (dt D > M_ii, MuJoCo's joint-space inertia
at qpos0 with armature) takes its gathered force through the drive's velocity target instead: PhysX adds `qf`
explicitly (dt F / M_ii) before the implicit damping takes nearly all of it back, and float32 loses the difference;
in the target the force is solved with the damping. A drive with a force limit keeps `qf` (the limit must not clamp
it). Tested by tests/test_loader_limit.py::test_a_limit_force_on_a_light_damped_link_goes_through_the_drive."""

from __future__ import annotations

import numpy as np

from ..model import drive, mj
from ..model.drive import DofDrive
from .dof_step import DofKey, Step, clear_qf
from .term import Compilation, Handover, Term

REGIME_ROWS = [0, 1, 3, 5]  # the law's rows a regime is made of: stiffness, damping, force limit, implicit extra
REGIMES = 64  # regimes kept: every regular one, and the clamped steps' (a clamp that binds step after step)


class DriveRegime:
    """What the drive writer derives from a step's stiffness, damping, force limit and implicit extra: PhysX's
    damping (`DofDrive.physx_damping`), which DoFs have stiffness (`stiff`) or damping (`damped`), and the heavy
    ones whose force rides on the velocity target. Every regular step (`Step.regular`) has the same."""

    def __init__(self, law: np.ndarray, timestep: float, mass: np.ndarray, flat: np.ndarray):
        self.stiffness, self.force_limit = law[0].copy(), law[3].copy()
        damping = law[1] + law[5]
        damping -= self.stiffness * timestep
        self.damping = np.maximum(damping, 0.0)
        self.heavy = ((timestep * self.damping > mass) & (self.force_limit == np.inf)).nonzero()[0]
        self.heavy_flat = flat[self.heavy]
        self.stiff, self.damped = self.stiffness > 0, self.damping > 0
        self.all_stiff, self.any_stiff = bool(self.stiff.all()), bool(self.stiff.any())
        self.all_damped, self.any_damped = bool(self.damped.all()), bool(self.damped.any())

    def position_target(self, constant: np.ndarray, offset: np.ndarray | None, timestep: float) -> np.ndarray:
        """constant / stiffness (+ offset dt) where the drive has stiffness, else 0; takes the constant out of
        `constant` there."""
        if not self.any_stiff:
            return np.zeros(constant.shape)
        if self.all_stiff:
            target = constant / self.stiffness
            if offset is not None:
                target += offset * timestep
            constant[:] = 0.0
            return target
        target = np.divide(constant, self.stiffness, out=np.zeros(constant.shape), where=self.stiff)
        if offset is not None:
            np.add(target, offset * timestep, out=target, where=self.stiff)
        constant[..., self.stiff] = 0.0
        return target

    def velocity_target(self, left: np.ndarray, offset: np.ndarray | None) -> np.ndarray:
        """left / damping (+ offset) where the drive has damping, else 0; takes it out of `left` there."""
        if not self.any_damped:
            return np.zeros(left.shape)
        if self.all_damped:
            target = left / self.damping
            if offset is not None:
                target += offset
            left[:] = 0.0
            return target
        target = np.divide(left, self.damping, out=np.zeros(left.shape), where=self.damped)
        if offset is not None:
            np.add(target, offset, out=target, where=self.damped)
        left[..., self.damped] = 0.0
        return target


class DriveWriter(Term):
    """Writes drives and `qf`: each drive DoF's law (`drive.apply`, as arrays), the PhysX calls only for the joints
    whose settings changed since the last write (`written`: stiffness, damping, force limit, target and velocity
    target as last written; NaN: unknown, written next step)
    (tests/test_loader_drives.py::test_a_changed_target_or_gain_reaches_physx_after_a_cached_step)."""

    name = "drives"

    def __init__(self, passive: dict[DofKey, DofDrive], inertia: dict[DofKey, float] | None = None):
        self.passive = passive
        self.inertia = {} if inertia is None else inertia  # M_ii at qpos0 (`dof_inertia`); absent: qf only
        self.written: np.ndarray | None = None  # `compile`'s

    def compile(self, compilation: Compilation) -> None:
        """`offsets`: whether any drive carries a velocity offset (the `slides` term is planned); without, adding it
        is skipped."""
        layout = compilation.layout
        self.layout, self.offsets = layout, "slides" in compilation.planned
        self.mass = np.array([self.inertia.get(key, np.inf) for key in layout.keys], dtype=np.float64)
        self.written = np.full((5, len(layout.keys)), np.nan)
        self.regimes: dict[object, DriveRegime] = {}  # a regular step's by Step.explicit_kv, others by their law
        self.idle = layout.size == 0  # no joint to drive, no qf to write

    def contribute(self, step: Step) -> None:
        """`drive.apply` on every drive DoF at once: the position target carries the constant where the drive has
        stiffness, the velocity target what is left where it has damping, `qf` the rest."""
        regime, target, velocity_target = self.split(step)
        self.write(np.array([regime.stiffness, regime.damping, regime.force_limit, target, velocity_target]))
        self.write_qf(step)

    def batch(self, step: Step, steps: list[Step], terms: list[DriveWriter]) -> bool:
        """Every copy's targets at once on a regular step (every copy's regime is the same); each copy's own writer
        writes its PhysX joints."""
        if not step.regular:
            return False
        regime, target, velocity_target = self.split(step)
        for k, (copy, writer) in enumerate(zip(steps, terms)):
            writer.write(
                np.array([regime.stiffness, regime.damping, regime.force_limit, target[k], velocity_target[k]])
            )
            writer.write_qf(copy)
        return True

    def split(self, step: Step) -> tuple[DriveRegime, np.ndarray, np.ndarray]:
        """The step's drive regime, position and velocity targets; what neither target carries joins `step.force`."""
        law, force, timestep = step.law, step.force, step.timestep
        first = law if law.ndim == 2 else law[:, 0]  # a batch's only on a regular step: every copy's is the same
        key = step.explicit_kv if step.regular else first[REGIME_ROWS].tobytes()
        regime = self.regimes.get(key)
        if regime is None:
            if len(self.regimes) >= REGIMES:
                self.regimes.clear()
            regime = self.regimes[key] = DriveRegime(first, timestep, self.mass, self.layout.flat)
        constant, via_damping = law[2], law[4]
        if regime.heavy.size:
            via_damping[..., regime.heavy] += force[..., regime.heavy_flat]
            force[..., regime.heavy_flat] = 0.0
        offset = law[6] if self.offsets else None
        target = regime.position_target(constant, offset, timestep)
        constant += via_damping  # what is left after the position target
        velocity_target = regime.velocity_target(constant, offset)
        force[..., self.layout.flat] += constant
        return regime, target, velocity_target

    @staticmethod
    def write_qf(step: Step) -> None:
        """The gathered generalized forces, per articulation, as PhysX's `qf`: SAPIEN rounds the float64 to its
        float32 as `astype` does, without the copy
        (tests/test_loader_drives.py::test_qf_is_written_as_float64_and_held_as_its_float32_rounding)."""
        if len(step.articulations) == 1:
            if step.articulations[0].dof:
                step.articulations[0].set_qf(step.force)
            return
        for articulation, qf in zip(step.articulations, step.layout.split(step.force)):
            if articulation.dof:
                articulation.set_qf(qf)

    def write(self, settings: np.ndarray) -> None:
        """The PhysX calls for the settings (rows as `written`) that differ from the last ones written."""
        changed = settings != self.written
        self.written = settings
        if not np.count_nonzero(changed):
            return
        joints = self.layout.joints
        for i in (changed[0] | changed[1] | changed[2]).nonzero()[0].tolist():
            joints[i].set_drive_properties(float(settings[0, i]), float(settings[1, i]), float(settings[2, i]), "force")
        for i in changed[3].nonzero()[0].tolist():
            joints[i].set_drive_target(float(settings[3, i]))
        for i in changed[4].nonzero()[0].tolist():
            joints[i].set_drive_velocity_target(float(settings[4, i]))

    def release(self, handover: Handover) -> None:
        """Every DoF's passive spring-damper in its drive, `qf` cleared."""
        joints = handover.joints
        for (art, dof), passive in self.passive.items():
            drive.apply(joints[art][dof], passive, passive.constant, handover.timestep)
        clear_qf(handover.articulations)
        if self.written is not None:
            self.written[:] = np.nan


def dof_inertia(model, mapping) -> dict[DofKey, float]:
    """MuJoCo's joint-space inertia diagonal (armature included) at qpos0, per hinge/slide DoF."""
    data = mj.forward_at(model)
    diagonal = data.M[model.M_rowadr + model.M_rownnz - 1]  # a row of the sparse lower triangle ends on its diagonal
    return {key: float(diagonal[d]) for key, d in mapping.mujoco_dofs().items()}
