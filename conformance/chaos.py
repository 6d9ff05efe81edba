"""How chaotic is a horizon? MuJoCo against itself under a 1e-6 perturbation of the initial state."""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from .commands import rng
from .reference import Rollout, qpos_difference, rollout


@dataclass(frozen=True)
class ChaosGate:
    """Amplification of the perturbation per step, and the longest horizon it stays under the limit."""

    perturbation: float
    amplification: np.ndarray  # (T+1,) max |dq| / perturbation
    limit: float
    judged_steps: int  # steps from the start over which the rollout may be judged
    steps: int

    @property
    def chaotic(self) -> bool:
        return self.judged_steps < self.steps

    def held(self, agreed: bool) -> ChaosGate:
        """The whole horizon judged where SAPIEN agreed with MuJoCo over all of it (`agreed`): MuJoCo's own
        sensitivity excuses a disagreement, it does not hide an agreement (tests/test_conformance_chaos.py)."""
        return replace(self, judged_steps=self.steps) if agreed and self.chaotic else self

    def to_dict(self) -> dict:
        return {
            "perturbation": self.perturbation,
            "amplification_max": float(self.amplification.max()),
            "amplification_limit": self.limit,
            "judged_steps": self.judged_steps,
            "steps": self.steps,
        }


def perturbed(model: mujoco.MjModel, qpos: np.ndarray, size: float, seed: int) -> np.ndarray:
    """qpos moved by `size` along a seeded random unit direction of the tangent space."""
    direction = rng(seed, "chaos").standard_normal(model.nv)
    direction *= size / max(np.linalg.norm(direction, ord=np.inf), 1e-300)
    out = np.array(qpos, dtype=float)
    mujoco.mj_integratePos(model, out, direction, 1.0)
    return out


def gate(model: mujoco.MjModel, reference: Rollout, seed: int, perturbation: float, limit: float) -> ChaosGate:
    """Replay the reference's commands from a perturbed start; cut the horizon where the gap grows > limit x."""
    steps = reference.command.shape[0]
    start = perturbed(model, reference.qpos[0], perturbation, seed)
    other = rollout(model, start, reference.qvel[0], steps, reference.command, reference.ctrl)
    gap = np.abs(qpos_difference(model, reference.qpos, other.qpos)).max(axis=1) if model.nv else np.zeros(steps + 1)
    amplification = gap / perturbation
    over = np.nonzero(amplification > limit)[0]
    judged = int(over[0]) - 1 if over.size else steps
    return ChaosGate(perturbation, amplification, limit, max(judged, 0), steps)
