"""Divergence: a SAPIEN run that leaves the finite, physical states MuJoCo's run stays in.

A state that is not finite, or a speed past a bound set by MuJoCo's own run (a multiple of the fastest speed
MuJoCo reaches in the same run, never below an absolute floor; `[settings.divergence]` in tolerances.toml), is
not an approximation any manifest reason can describe: the tier's outcome is `diverged`, always worse than what the
manifest expects, and the first bad step is reported. MuJoCo runs that blow up themselves are skipped before
SAPIEN is compared (`reference.Rollout.unstable`), so a divergence here is SAPIEN's alone.
Tested by tests/test_conformance_divergence.py."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class Divergence:
    """Where a SAPIEN run first left the physical states: which run, its step and time, and what was seen."""

    run: str
    step: int
    time: float
    what: str

    def text(self) -> str:
        return f"{self.run} step {self.step} (t = {self.time:.3g} s): {self.what}"

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SpeedBound:
    """The largest speed (rad/s or m/s, any DoF) a SAPIEN run may reach: `factor` times MuJoCo's fastest in the
    same run, at least `floor`."""

    factor: float
    floor: float

    @classmethod
    def from_tolerances(cls, tolerances) -> SpeedBound:
        return cls(
            float(tolerances.setting("divergence", "speed_factor")),
            float(tolerances.setting("divergence", "speed_floor")),
        )

    def limit(self, mujoco_qvel) -> float:
        reference = np.abs(np.asarray(mujoco_qvel, dtype=float))
        fastest = float(reference[np.isfinite(reference)].max(initial=0.0))
        return max(self.floor, self.factor * fastest)


def first_divergence(run: str, qpos, qvel, mujoco_qvel, bound: SpeedBound, dt: float, steps=None) -> Divergence | None:
    """The first row of a SAPIEN run (qpos (T, nq), qvel (T, nv)) that is not finite or moves faster than the
    bound MuJoCo's run (`mujoco_qvel`, any shape) allows; `steps` names the rows' step numbers (default 0..T-1)."""
    qpos = np.asarray(qpos, dtype=float).reshape(len(qpos), -1)
    qvel = np.asarray(qvel, dtype=float).reshape(len(qvel), -1)
    steps = np.arange(len(qpos)) if steps is None else np.asarray(steps)
    limit = bound.limit(mujoco_qvel)
    finite = np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1)
    speed = np.where(np.isfinite(qvel), np.abs(qvel), 0.0).max(axis=1, initial=0.0)
    bad = np.flatnonzero(~finite | (speed > limit))
    if bad.size == 0:
        return None
    row = int(bad[0])
    if not finite[row]:
        parts = [name for name, values in (("qpos", qpos[row]), ("qvel", qvel[row])) if not np.isfinite(values).all()]
        what = " and ".join(parts) + " not finite"
    else:
        what = f"|qvel| {speed[row]:.4g} above the bound {limit:.4g} (rad/s or m/s)"
    step = int(steps[row])
    return Divergence(run, step, step * dt, what)


def first_of(*found: Divergence | None) -> Divergence | None:
    """The divergence of the first run (in the order the tier ran them) that diverged, or None."""
    return next((d for d in found if d is not None), None)
