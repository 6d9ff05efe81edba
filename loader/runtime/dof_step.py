"""One step's working record as arrays: the joint state and the generalized forces over every articulation's DoFs
end to end (`flat`), and per hinge/slide DoF (a drive DoF) the force law its PhysX drive will carry. Every per-step
term reads and adds to these, in the controller's stage order (`controller.py`); the drive writer turns them into
PhysX settings at the end. `DofLayout` is what the arrays index, planned once at load."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..model.drive import DofDrive
from ..model.joints import dof_damping, joint_stiffness
from ..model.mapping import Mapping

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
        return [flat[starts[a] : starts[a + 1]] for a in range(len(starts) - 1)]


def law_arrays(laws: list[DofDrive]) -> np.ndarray:
    """Rows stiffness, damping, constant, force limit of these laws, one column per drive DoF."""
    return (
        np.array([[law.stiffness, law.damping, law.constant, law.force_limit] for law in laws], dtype=np.float64)
        .reshape(-1, 4)
        .T.copy()
    )


@dataclass
class Step:
    """One `set_ctrl`'s record: the state every term reads and what the terms gather, in stage order. Each field
    says which stage writes it; every later stage may read it.

    `law` has one column per drive DoF (`layout.keys`) and these rows: stiffness, damping, constant (the law's
    state-independent part), force limit (the actuators start them from the planned laws; the stiffness and
    clamps stages change them), via_damping (a constant force the velocity target carries, `drive.apply`; the
    clamps), implicit_extra (implicit damping that joins the drive's: the tendon dampers' and tendon actuators'
    implicit diagonal), offset (the velocity the drive's measure is short of: `slides`). The `drives` stage
    writes them to PhysX."""

    articulations: list  # read by every stage
    joints: list[list]  # PhysX joints per articulation (rows, drives)
    layout: DofLayout
    q: np.ndarray  # state: joint positions end to end over the articulations' DoFs
    v: np.ndarray  # state: joint velocities, likewise
    force: np.ndarray  # every stage adds its generalized force here; `drives` writes it as `qf`
    law: np.ndarray  # see above
    inputs: np.ndarray  # ctrl stage: what each actuator's gain multiplies (clamped ctrl, or the activation)
    ctrl: np.ndarray  # ctrl stage: MuJoCo's ctrl, clamped to ctrlrange
    act: np.ndarray | None  # ctrl stage: MuJoCo's act at the start of the step (None: no activation dynamics)
    qfrc_applied: np.ndarray | None  # the caller's generalized force, MuJoCo's layout
    actuated: bool  # the actuators term is on (off: MuJoCo's actuation disabled)
    timestep: float
    explicit_kv: bool  # Euler or RK4: actuator kv is explicit
    advance: bool  # the first `set_ctrl` of this physics step (activations, link forces)
    # no clamp bound, no tendon actuator saturated (written False by the actuators stage): stiffness, damping, force
    # limit and implicit extra are every such step's (with the same explicit_kv), what is derived from them reused
    regular: bool = True
    state: tuple | None = field(default=None, repr=False)  # `mujoco_state`, converted once
    # rows: MuJoCo's data of the runtime's model at this step's start state, its forward pass run (M, bias and
    # passive forces computed), for a later stage to read instead of running MuJoCo's passes again (`drives`)
    forwarded: mujoco.MjData | None = field(default=None, repr=False)

    def renew(self, q, v, inputs, ctrl, act, qfrc_applied, actuated: bool, advance: bool) -> Step:
        """This record as the next step's, where MuJoCo's step writes its whole `force` and reads no drive law
        (`MujocoStep.record`): the state and command replaced, nothing derived from the last kept."""
        self.q, self.v, self.inputs, self.ctrl, self.act = q, v, inputs, ctrl, act
        self.qfrc_applied, self.actuated, self.advance = qfrc_applied, actuated, advance
        self.regular, self.state, self.forwarded = True, None, None
        return self

    def mujoco_state(self, mapping) -> tuple[np.ndarray, np.ndarray]:
        """The step's start state in MuJoCo's layout (qpos, qvel), converted once for every term that reads it."""
        if self.state is None:
            self.state = mapping.get_state(self.articulations, self.layout.split(self.q), self.layout.split(self.v))
        return self.state

    @property
    def stiffness(self) -> np.ndarray:
        return self.law[0]

    @property
    def damping(self) -> np.ndarray:
        return self.law[1]

    @property
    def constant(self) -> np.ndarray:
        return self.law[2]

    @property
    def force_limit(self) -> np.ndarray:
        return self.law[3]

    @property
    def via_damping(self) -> np.ndarray:
        return self.law[4]

    @property
    def implicit_extra(self) -> np.ndarray:
        return self.law[5]

    @property
    def offset(self) -> np.ndarray:
        return self.law[6]


def passive_laws(model: mujoco.MjModel, mapping: Mapping) -> dict[DofKey, DofDrive]:
    """Every hinge/slide DoF's passive spring-damper (MuJoCo's terms), the law its drive has without actuators."""
    laws = {}
    for j, target in enumerate(mapping.joints):
        if target.drive_key is not None:
            stiffness = joint_stiffness(model, j)
            laws[target.drive_key] = DofDrive(
                stiffness,
                dof_damping(model, int(model.jnt_dofadr[j])),
                stiffness * float(model.qpos_spring[model.jnt_qposadr[j]]) if stiffness else 0.0,
            )  # 0 * inf
    return laws


def clear_qf(articulations) -> None:
    """No joint force left in PhysX (`set_qf` persists until written again)."""
    for articulation in articulations:
        if articulation.dof:
            articulation.set_qf(np.zeros(articulation.dof, np.float32))


def refresh_link_velocities(articulations) -> None:
    """Make a fixed-base articulation's link velocities the ones its joint velocities imply.

    After a step, a fixed-base articulation's links keep the solver's velocities, which carry dt times each
    link's velocity-product acceleration on top of what the new joint velocities imply (a floating base's are
    rebuilt at once). Per-step terms that read link velocities read them after this; writing the joint velocities
    back leaves the dynamics as they are
    (tests/test_loader_connect.py::test_rows_read_on_the_links_drifted_velocities_miss_the_falling_loop)."""
    for articulation in articulations:
        if articulation.dof and articulation.root.joint.type == "fixed":
            articulation.set_qvel(articulation.get_qvel())
