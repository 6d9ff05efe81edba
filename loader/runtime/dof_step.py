"""One step's working record: per hinge/slide DoF the force law its PhysX drive will carry (`DofStep`), and per
articulation the generalized forces gathered for `set_qf` (`Step`). Every per-step term reads and adds to these, in
the controller's stage order (`controller.py`); the drive writer turns them into PhysX settings at the end."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..build.joint import dof_damping, joint_stiffness
from ..build.mapping import Mapping
from ..drive import DofDrive

DofKey = tuple[int, int]  # (articulation, SAPIEN dof)


@dataclass
class DofStep:
    """What one DoF's drive carries this step: its law, the law's state-independent part, a constant force the
    velocity target carries (`drive.apply`'s `via_damping`), and implicit damping that joins the drive's damping
    (the implicit diagonal of tendon dampers and tendon actuators' kv)."""

    law: DofDrive
    constant: float
    via_damping: float = 0.0
    implicit_extra: float = 0.0


@dataclass
class Step:
    """The state the terms read and the forces they gather, for one `set_ctrl`."""

    articulations: list
    joints: list[list]  # per articulation, its active joints
    q: list[np.ndarray]
    v: list[np.ndarray]
    forces: list[np.ndarray]  # per articulation, the generalized force `set_qf` gets
    dofs: dict[DofKey, DofStep]
    inputs: np.ndarray  # what each actuator's gain multiplies: clamped ctrl, or the activation
    timestep: float
    explicit_kv: bool  # Euler or RK4: actuator kv is explicit
    advance: bool  # the first `set_ctrl` of this physics step (activations and link forces advance once)
    offsets: dict[DofKey, float] = field(default_factory=dict)  # drive velocity offsets (`slides.py`)

    def add(self, key: DofKey, force: float) -> None:
        self.forces[key[0]][key[1]] += force


def passive_laws(model: mujoco.MjModel, mapping: Mapping) -> dict[DofKey, DofDrive]:
    """Every hinge/slide DoF's passive spring-damper (MuJoCo's terms), the law its drive has without actuators."""
    laws = {}
    for j, target in enumerate(mapping.joints):
        if target.kind in ("hinge", "slide"):
            stiffness = joint_stiffness(model, j)
            laws[(target.articulation, target.dofs[0])] = DofDrive(
                stiffness, dof_damping(model, int(model.jnt_dofadr[j])),
                stiffness * float(model.qpos_spring[model.jnt_qposadr[j]]))
    return laws


@dataclass
class ArmatureWriter:
    """The PhysX armature of DoFs whose implicit damping a constraint row moves into it, written only on change."""

    written: dict[DofKey, float] = field(default_factory=dict)

    def set(self, joint, key: DofKey, armature: float, unset: float | None = None) -> None:
        """Write `armature` when it differs from the last written (`unset`: what the joint has if never)."""
        if self.written.get(key, unset) != armature:
            joint.set_armature(np.array([armature], np.float32))
            self.written[key] = armature

    def armature_form(self, step: Step, key: DofKey, own_armature: float, law: DofDrive, constant: float) -> float:
        """Free the DoF's drive for a constraint row (friction, limit): its implicit damping D becomes armature
        dt D plus the explicit force -D v, its stiffness and constant explicit forces. Returns D."""
        art, dof = key
        record = step.dofs[key]
        damping = law.damping + record.implicit_extra
        record.implicit_extra = 0.0
        step.add(key, constant + record.via_damping - law.stiffness * step.q[art][dof] - damping * step.v[art][dof])
        record.via_damping = 0.0
        self.set(step.joints[art][dof], key, own_armature + step.timestep * damping)
        return damping
