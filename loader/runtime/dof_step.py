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
    ctrl: np.ndarray  # MuJoCo's ctrl, clamped to ctrlrange
    act: np.ndarray | None  # MuJoCo's act at the start of the step (None: no activation dynamics)
    qfrc_applied: np.ndarray | None  # the caller's generalized force, MuJoCo's layout
    actuated: bool  # the actuators term is on (off: MuJoCo's actuation disabled, as `disable_actuators` means)
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
                stiffness * float(model.qpos_spring[model.jnt_qposadr[j]]) if stiffness else 0.0)  # 0 * inf
    return laws
