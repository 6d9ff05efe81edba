"""One step's working record as arrays: the joint state and the generalized forces over every articulation's DoFs
end to end (`flat`), and per hinge/slide DoF (a drive DoF) the force law its PhysX drive will carry. Every per-step
term reads and adds to these, in the controller's stage order (`controller.py`); the drive writer turns them into
PhysX settings at the end. `DofLayout` is what the arrays index, planned once at load."""

from __future__ import annotations

import mujoco
import numpy as np

from ..build.joint import dof_damping, joint_stiffness
from ..build.mapping import Mapping
from ..drive import DofDrive

DofKey = tuple[int, int]  # (articulation, SAPIEN dof)


class DofLayout:
    """Where each drive DoF sits: `keys[i]` its (articulation, dof), `flat[i]` its place in the articulations'
    DoFs end to end (`starts[a]` is articulation a's first), `joints[i]` its PhysX joint; `links[a]` articulation
    a's links."""

    def __init__(self, articulations: list, keys: list[DofKey]):
        sizes = [int(art.dof) for art in articulations]
        self.starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.size = int(self.starts[-1])
        self.keys = list(keys)
        self.index = {key: i for i, key in enumerate(self.keys)}
        self.flat = np.array([self.starts[a] + d for a, d in self.keys], dtype=int)
        joints = [art.active_joints for art in articulations]
        self.joints = [joints[a][d] for a, d in self.keys]
        self.links = [art.links for art in articulations]  # per articulation (the property builds a new list)

    def flat_of(self, keys) -> np.ndarray:
        return np.array([self.starts[a] + d for a, d in keys], dtype=int)

    def drive_of(self, keys) -> np.ndarray:
        return np.array([self.index[key] for key in keys], dtype=int)

    def read(self, articulations) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and velocities, end to end (float64)."""
        if not articulations:
            return np.zeros(0), np.zeros(0)
        if len(articulations) == 1:
            art = articulations[0]
            return np.asarray(art.get_qpos(), np.float64), np.asarray(art.get_qvel(), np.float64)
        q = np.concatenate([art.get_qpos() for art in articulations]).astype(np.float64)
        return q, np.concatenate([art.get_qvel() for art in articulations]).astype(np.float64)

    def split(self, flat: np.ndarray) -> list[np.ndarray]:
        """Per articulation, its part of an end-to-end array (views)."""
        starts = self.starts
        return [flat[starts[a]:starts[a + 1]] for a in range(len(starts) - 1)]


def law_arrays(laws: list[DofDrive]) -> np.ndarray:
    """Rows stiffness, damping, constant, force limit of these laws, one column per drive DoF."""
    return np.array([[law.stiffness, law.damping, law.constant, law.force_limit] for law in laws],
                    dtype=np.float64).reshape(-1, 4).T.copy()


class Step:
    """The state the terms read and the forces they gather, for one `set_ctrl`. Per drive DoF (columns of
    `layout.keys`): `stiffness`, `damping`, `constant` (the law's state-independent part), `force_limit`,
    `via_damping` (a constant force the velocity target carries, `drive.apply`), `implicit_extra` (implicit damping
    that joins the drive's: the implicit diagonal of tendon dampers and tendon actuators' kv) and `offset` (the
    velocity the drive's measure is short of, `slides.py`)."""

    def __init__(self, articulations, joints: list[list], layout: DofLayout, q, v, force, law: np.ndarray, inputs,
                 ctrl, act, qfrc_applied, actuated: bool, timestep: float, explicit_kv: bool, advance: bool):
        self.articulations, self.joints, self.layout = articulations, joints, layout  # joints: per articulation
        self.q, self.v, self.force = q, v, force  # end to end over the articulations' DoFs
        self.law = law  # rows: stiffness, damping, constant, force limit, via_damping, implicit_extra, offset
        self.inputs = inputs  # what each actuator's gain multiplies: clamped ctrl, or the activation
        self.ctrl = ctrl  # MuJoCo's ctrl, clamped to ctrlrange
        self.act = act  # MuJoCo's act at the start of the step (None: no activation dynamics)
        self.qfrc_applied = qfrc_applied  # the caller's generalized force, MuJoCo's layout
        self.actuated = actuated  # the actuators term is on (off: MuJoCo's actuation disabled)
        self.timestep = timestep
        self.explicit_kv = explicit_kv  # Euler or RK4: actuator kv is explicit
        self.advance = advance  # the first `set_ctrl` of this physics step (activations, link forces)
        self.regular = True  # no clamp bound, no tendon actuator saturated: stiffness, damping, force limit and
        # implicit extra are every such step's (with the same explicit_kv), what is derived from them is reused
        self._state: tuple | None = None

    def mujoco_state(self, mapping) -> tuple[np.ndarray, np.ndarray]:
        """The step's start state in MuJoCo's layout (qpos, qvel), converted once for every term that reads it."""
        if self._state is None:
            self._state = mapping.get_state(self.articulations, self.layout.split(self.q), self.layout.split(self.v))
        return self._state

    stiffness = property(lambda self: self.law[0])
    damping = property(lambda self: self.law[1])
    constant = property(lambda self: self.law[2])
    force_limit = property(lambda self: self.law[3])
    via_damping = property(lambda self: self.law[4])
    implicit_extra = property(lambda self: self.law[5])
    offset = property(lambda self: self.law[6])


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
