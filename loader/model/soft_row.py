"""MuJoCo's soft-constraint law (solref, solimp) for one constraint row: after one step a row is exactly an
implicit damper 1 / (dt R) pulling the row's velocity to J v0 + dt aref, which a PhysX drive is, whatever the
inertia. Derivation: docs/mapping.md#soft-rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from . import mj
from .mj import MJMINVAL

MINIMP, MAXIMP = 0.0001, 0.9999  # MuJoCo's bounds on a row's impedance (mjMINIMP, mjMAXIMP)


@dataclass(frozen=True)
class SoftRow:
    """solref and solimp of one constraint, with MuJoCo's refsafe clamp applied to the time constant."""

    stiffness: float  # K
    damping: float  # B
    solimp: tuple[float, float, float, float, float]  # dmin, dmax, width, midpoint, power

    @classmethod
    def of(cls, model: mujoco.MjModel, solref, solimp, timestep: float | None = None) -> SoftRow:
        """The row of `solref`, `solimp` for steps of `timestep` (None: the model's), which refsafe clamps against."""
        timestep = float(model.opt.timestep if timestep is None else timestep)
        timeconst, dampratio = (float(x) for x in solref)
        dmax = min(max(float(solimp[1]), MINIMP), MAXIMP)
        if timeconst > 0:
            if not mj.disabled(model, "refsafe"):
                timeconst = max(timeconst, 2.0 * timestep)
            stiffness = 1.0 / max(MJMINVAL, dmax * dmax * timeconst * timeconst * dampratio * dampratio)
            damping = 2.0 / max(MJMINVAL, dmax * timeconst)
        else:  # the direct form: -stiffness, -damping, scaled by dmax
            stiffness, damping = -timeconst / (dmax * dmax), -dampratio / dmax
        return cls(stiffness, damping, tuple(float(x) for x in solimp[:5]))

    def impedance(self, violation: float) -> float:
        """imp(|r|): solimp's sigmoid from dmin at r = 0 to dmax at r >= width."""
        dmin, dmax, width, midpoint, power = self.solimp
        dmin, dmax = (min(max(d, MINIMP), MAXIMP) for d in (dmin, dmax))
        if dmin == dmax or width <= MJMINVAL:
            return 0.5 * (dmin + dmax)
        x = abs(violation) / width
        if x >= 1.0 or x <= 0.0:
            return dmax if x >= 1.0 else dmin
        midpoint = min(max(midpoint, MJMINVAL), 1.0 - MJMINVAL)
        power = max(power, 1.0)
        if x <= midpoint:
            y = x**power / midpoint ** (power - 1.0)
        else:
            y = 1.0 - (1.0 - x) ** power / (1.0 - midpoint) ** (power - 1.0)
        return dmin + y * (dmax - dmin)

    def regularizer(self, imp: float, diag_approx: float) -> float:
        """R = (1 - imp) / imp * diagApprox."""
        return max(MJMINVAL, (1.0 - imp) * diag_approx / imp)

    def reference(self, imp: float, position, velocity):
        """aref without the velocity-product term: -B v - K imp r."""
        return -self.damping * np.asarray(velocity) - self.stiffness * imp * np.asarray(position)


def diag_approx(model: mujoco.MjModel, data: mujoco.MjData, constraint_type: int, index: int) -> np.ndarray:
    """MuJoCo's diagApprox of the rows of constraint `index` of `constraint_type` (mjtConstraint) in `data`
    (after a forward pass): a compile-time constant per row."""
    rows = (data.efc_type == constraint_type) & (data.efc_id == index)
    return np.asarray(data.efc_diagA[rows], dtype=float)
