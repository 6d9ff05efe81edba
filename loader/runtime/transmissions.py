"""Actuators whose transmission MuJoCo computes: a site (a wrench at it, or with a reference site a displacement
from it), a slider-crank, a joint or jointinparent transmission on a free joint. MuJoCo's `mj_transmission` gives
each its length and moment (its row of d length / d qpos, gear inside) at a pose; at SAPIEN's state every step
they are MuJoCo's own, the force law takes the length and the rate moment . qvel, and the force reaches the joints
as moment^T f: joint forces on hinges and slides, a wrench on a free joint's root link. This is a spatial tendon's
path with MuJoCo's actuator rows in place of its tendon rows, so it is carried the same way (`tendons.py`,
`actuators.SpatialActuators`) (tests/test_loader_transmissions.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from ..model.joints import DRIVEN
from ..model.mapping import Mapping
from .tendons import TendonPaths


class MomentPaths(TendonPaths):
    """The actuators `actuators` (MuJoCo ids) over the DoFs `dofs` (MuJoCo's) their transmissions can move: their
    lengths and moments at a pose, once per step for every consumer. MuJoCo keeps the moments sparse with the
    pattern of the values (an entry that is zero at a pose is left out), so each is spread out per pose."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, actuators: list[int]):
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.tendons = np.array(actuators, dtype=int)  # the rows: the paths' consumers index them alike
        self.dofs = np.array(sorted(set().union(*(mj.transmission_dofs(model, a) for a in actuators))), dtype=int)
        targets = [mapping.joints[int(model.dof_jntid[d])] for d in self.dofs]
        self.joint = np.array([t.kind in DRIVEN for t in targets], dtype=bool)
        self.floating = not self.joint.all()
        self.keys = [(t.articulation, t.dofs[0]) for t, on in zip(targets, self.joint) if on]
        self.column = np.full(model.nv, -1, dtype=int)
        self.column[self.dofs] = np.arange(self.dofs.size)
        self.row_of = np.full(model.nu, -1, dtype=int)
        self.row_of[self.tendons] = np.arange(self.tendons.size)
        self.last = None

    def measure(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The actuators' lengths and moments (actuator x `dofs`) at MuJoCo's `qpos`."""
        model, data = self.model, self.data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        mujoco.mj_transmission(model, data)
        return data.actuator_length[self.tendons], self.dense(data)

    def dense(self, data: mujoco.MjData) -> np.ndarray:
        """The actuators' rows of MuJoCo's sparse moment, over `dofs`."""
        counts = data.moment_rownnz
        owner = np.repeat(np.arange(self.model.nu), counts)  # each entry's actuator, in row order
        entry = data.moment_rowadr[owner] + np.arange(owner.size) - (np.cumsum(counts) - counts)[owner]
        rows, columns = self.row_of[owner], self.column[data.moment_colind[entry]]
        kept = (rows >= 0) & (columns >= 0)
        moment = np.zeros((self.tendons.size, self.dofs.size))
        moment[rows[kept], columns[kept]] = data.actuator_moment[entry[kept]]
        return moment


def plan_moments(model: mujoco.MjModel, mapping: Mapping, actuators: list[int]) -> MomentPaths | None:
    """The paths of the mapped actuators whose moment MuJoCo computes (None without any)."""
    return MomentPaths(model, mapping, actuators) if actuators else None
