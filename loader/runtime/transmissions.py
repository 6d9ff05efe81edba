"""Actuators whose transmission MuJoCo computes: a site (a wrench at it, or with a reference site a displacement
from it), a slider-crank, a joint or jointinparent transmission on a free joint. MuJoCo's `mj_transmission` gives
each its length and moment (its row of d length / d qpos, gear inside) at a pose; at SAPIEN's state every step
they are MuJoCo's own, the force law takes the length and the rate moment . qvel, and the force reaches the joints
as moment^T f: joint forces on hinges and slides, a wrench on a free joint's root link. This is a spatial tendon's
path with MuJoCo's actuator rows in place of its tendon rows, so it is carried the same way (`tendons.py`,
`actuators.SpatialActuators`) (tests/test_loader_transmissions.py).

A body transmission (`<adhesion>`) has length 0 and as moment minus the mean of the normal Jacobians of the
body's contacts (an active contact's from its constraint rows, one in its geoms' gap from the two bodies'
Jacobians), so MuJoCo's copy runs its collision and makes its constraint rows at SAPIEN's pose before
`mj_transmission`: the passes of `mj_forward` that moment reads, the same numbers as the whole forward pass
(tests/test_loader_transmissions.py::test_a_body_moment_is_mujocos_forward_pass_at_every_pose). While SAPIEN's
contacts are off, MuJoCo's copy has none either, and the moment is zero, as under `<flag contact="disable">`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..model import mj
from ..model.mapping import Mapping
from ..model.mj import MJMINVAL
from .dof_step import Step
from .tendons import AlongPaths, TendonPaths

RATE_STEP = 1e-4  # of a muscle's velocity scale (optimal length x vmax): the step of its gain's central difference


class MomentPaths(TendonPaths):
    """The actuators `actuators` (MuJoCo ids) over the DoFs `dofs` (MuJoCo's) their transmissions can move: their
    lengths and moments at a pose, once per step for every consumer. MuJoCo keeps the moments sparse with the
    pattern of the values (an entry that is zero at a pose is left out), so each is spread out per pose."""

    def __init__(self, model: mujoco.MjModel, mapping: Mapping, actuators: list[int]):
        self.model, self.mapping = model, mapping
        self.data = mujoco.MjData(model)
        self.tendons = np.array(actuators, dtype=int)  # the rows: the paths' consumers index them alike
        self.over(sorted(set().union(*(mj.transmission_dofs(model, a) for a in actuators))))
        self.column = np.full(model.nv, -1, dtype=int)
        self.column[self.dofs] = np.arange(self.dofs.size)
        self.row_of = np.full(model.nu, -1, dtype=int)
        self.row_of[self.tendons] = np.arange(self.tendons.size)
        self.last = None
        body = int(mujoco.mjtTrn.mjTRN_BODY)
        self.adhesive = any(int(model.actuator_trntype[a]) == body for a in actuators)  # reads the contacts
        self.touching = True  # SAPIEN has contacts (`contacts`)

    def contacts(self, enabled: bool) -> None:
        """SAPIEN's contacts switched on or off: MuJoCo's copy collides only while they are on."""
        self.touching = enabled
        self.last = None

    def pose(self, qpos: np.ndarray) -> mujoco.MjData:
        """`TendonPaths.pose`, and where a body transmission reads contacts, MuJoCo's collision at that pose and the
        constraint rows its active contacts make (none while SAPIEN's contacts are off)."""
        data = super().pose(qpos)
        if self.adhesive:
            if self.touching:
                model = self.model
                if model.nflex:
                    mujoco.mj_flex(model, data)
                mujoco.mj_collision(model, data)
                mujoco.mj_makeConstraint(model, data)
            else:
                data.ncon = 0
        return data

    def measure(self, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The actuators' lengths and moments (actuator x `dofs`) at MuJoCo's `qpos`."""
        data = self.pose(qpos)
        mujoco.mj_transmission(self.model, data)
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


class MuscleLaws:
    """MuJoCo's muscles among the actuators `indices`: force = gain(L, V) x activation + bias(L), the curves of
    `mju_muscleGain` and `mju_muscleBias` at the actuator's length L and rate V (MuJoCo's own functions, with the
    compiled `lengthrange` and `acc0`), clamped to forcerange. MuJoCo's implicit integrators hold the force's rate
    derivative, activation x dgain/dV, implicitly (none once a forcerange clamps it); `damping` gives it as a
    damping, its derivative a central difference of MuJoCo's own curve, which is quadratic in V piece by piece."""

    def __init__(self, model: mujoco.MjModel, indices: list[int]):
        self.indices = np.array(indices, dtype=int)
        self.lengthrange = [np.array(model.actuator_lengthrange[a], dtype=np.float64) for a in indices]
        self.acc0 = [float(model.actuator_acc0[a]) for a in indices]
        self.gainprm = [np.array(model.actuator_gainprm[a, :9], dtype=np.float64) for a in indices]
        self.biasprm = [np.array(model.actuator_biasprm[a, :9], dtype=np.float64) for a in indices]
        self.biased = [int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_MUSCLE) for a in indices]
        span = [max(float(p[1] - p[0]), MJMINVAL) for p in self.gainprm]  # the normalized length range
        optimum = [float(r[1] - r[0]) / s for r, s in zip(self.lengthrange, span)]  # L0, the optimal length
        self.step = [RATE_STEP * max(o * float(p[6]), MJMINVAL) for o, p in zip(optimum, self.gainprm)]
        limited = model.actuator_forcelimited[indices].astype(bool)
        self.low = np.where(limited, model.actuator_forcerange[indices, 0], -np.inf)
        self.high = np.where(limited, model.actuator_forcerange[indices, 1], np.inf)

    def force(self, inputs: np.ndarray, length: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Each muscle's force from its activation (`inputs`, the muscles' own), length and rate."""
        out = np.empty(len(self.indices))
        for i, (act, length_i, velocity_i) in enumerate(zip(inputs.tolist(), length.tolist(), velocity.tolist())):
            lengthrange, acc0 = self.lengthrange[i], self.acc0[i]
            gain = mujoco.mju_muscleGain(length_i, velocity_i, lengthrange, acc0, self.gainprm[i])
            bias = mujoco.mju_muscleBias(length_i, lengthrange, acc0, self.biasprm[i]) if self.biased[i] else 0.0
            out[i] = gain * act + bias
        return np.minimum(np.maximum(out, self.low), self.high)

    def damping(self, inputs: np.ndarray, length: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """-activation x dgain/dV of each muscle: the damping MuJoCo's implicit integrators hold."""
        out = np.empty(len(self.indices))
        for i, (act, length_i, velocity_i) in enumerate(zip(inputs.tolist(), length.tolist(), velocity.tolist())):
            lengthrange, acc0, prm, h = self.lengthrange[i], self.acc0[i], self.gainprm[i], self.step[i]
            up = mujoco.mju_muscleGain(length_i, velocity_i + h, lengthrange, acc0, prm)
            down = mujoco.mju_muscleGain(length_i, velocity_i - h, lengthrange, acc0, prm)
            out[i] = -act * (up - down) / (2.0 * h)
        return out


class MuscleActuators(AlongPaths):
    """The mapped muscles along `paths` (a `MomentPaths` that holds their rows)."""

    def __init__(self, model: mujoco.MjModel, muscles: list[int], paths: MomentPaths, implicit_kv):
        super().__init__(paths, muscles)
        self.laws = MuscleLaws(model, muscles)
        self.implicit_kv = implicit_kv  # (damping, saturated) -> the damping MuJoCo's implicit step keeps

    def contribute(self, step: Step) -> None:
        length, moment, v = self.paths.state(step)
        moment, inputs, length = moment[self.rows], step.inputs[self.laws.indices], length[self.rows]
        rate = moment @ v
        force = self.laws.force(inputs, length, rate)
        implicit = None
        if not step.explicit_kv:
            unclamped = (force > self.laws.low) & (force < self.laws.high)
            implicit = self.implicit_kv(self.laws.damping(inputs, length, rate), ~unclamped)
            step.regular = False  # the damping changes with the state
        self.paths.apply(step, moment.T @ force, self.push, moment, v, implicit)


def plan_moments(model: mujoco.MjModel, mapping: Mapping, actuators: list[int]) -> MomentPaths | None:
    """The paths of the mapped actuators whose moment MuJoCo computes (None without any)."""
    return MomentPaths(model, mapping, actuators) if actuators else None
