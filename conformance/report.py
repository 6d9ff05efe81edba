"""What a tier returns: metrics with tolerance and margin, a status, and the series it measured."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .divergence import Divergence

STATUSES = ("pass", "fail", "chaotic", "skipped", "diverged")


@dataclass
class Metric:
    """One compared quantity: max and RMS of the error against its tolerance; margin = tolerance - max."""

    name: str
    max: float
    rms: float
    tolerance: float
    unit: str
    count: int = 0
    raw_max: float | None = None  # where the judged error is what float32 cannot resolve subtracted: the raw max

    @property
    def margin(self) -> float:
        return self.tolerance - self.max

    @property
    def passed(self) -> bool:
        return bool(self.max <= self.tolerance)  # NaN fails

    def to_dict(self) -> dict:
        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        out = {
            "name": self.name,
            "max": num(self.max),
            "rms": num(self.rms),
            "tolerance": self.tolerance,
            "margin": num(self.margin),
            "unit": self.unit,
            "count": self.count,
            "passed": self.passed,
        }
        if self.raw_max is not None:
            out["raw_max"] = num(self.raw_max)
        return out


def metric(name: str, errors, tolerance: float, unit: str, floor=None) -> Metric:
    """Max and RMS of the absolute errors; no samples gives a zero metric with count 0. With `floor` (per
    sample, what float32 cannot resolve) the judged errors are |error| - floor (at least 0), and the raw max is
    kept beside them."""
    raw = np.abs(np.asarray(errors, dtype=float))
    err = (np.maximum(raw - np.asarray(floor, dtype=float), 0.0) if floor is not None else raw).ravel()
    raw_max = float(raw.max()) if floor is not None and raw.size and np.all(np.isfinite(raw)) else None
    if err.size == 0:
        return Metric(name, 0.0, 0.0, tolerance, unit, 0)
    if not np.all(np.isfinite(err)):
        return Metric(name, math.inf, math.inf, tolerance, unit, int(err.size))
    return Metric(name, float(err.max()), float(np.sqrt(np.mean(err**2))), tolerance, unit, int(err.size), raw_max)


@dataclass
class Trace:
    """A compared rollout: times, both sides' joint positions (MuJoCo layout), the command, body poses.

    Poses are world (x, y, z, qw, qx, qy, qz) per step and MuJoCo body; SAPIEN poses are the links the
    mapping assigns to those bodies (NaN where a body has no link). The recording plays it in the 3D view."""

    name: str
    time: np.ndarray  # (T,)
    mujoco_qpos: np.ndarray  # (T, nq)
    sapien_qpos: np.ndarray  # (T, nq)
    qpos_error: np.ndarray  # (T, nv) differentiated positions, SAPIEN - MuJoCo
    command: np.ndarray  # (T, nv) generalized force applied on both sides
    mujoco_body_pose: np.ndarray  # (T, nbody, 7)
    sapien_body_pose: np.ndarray  # (T, nbody, 7)
    sapien_link_pose: np.ndarray  # (T, L, 7) every articulation link, helper links included
    contact: bool = False  # whether both sides ran with contacts on


@dataclass
class ActuatorTrace:
    """Per-actuator series of an actuated rollout (T steps): the ctrl both sides received (after MuJoCo's
    ctrlrange clamp) and each side's actuator-space force at that step. MuJoCo: `data.actuator_force`. SAPIEN: the
    force law gain*ctrl + b0 + b1*length + b2*velocity, with the loaded model's gain and bias and the loader's
    gear and tendon coefficients (`result.actuators`), evaluated on the state read back from SAPIEN before the
    step and clamped to forcerange; for a joint actuator that is (gear*(gain*ctrl + b0) - stiffness*q -
    damping*qdot) / gear with the ActuatorMap's stiffness = -b1*gear^2 and damping = -b2*gear^2. It is not read
    back from PhysX: PhysX applies a drive implicitly (with the velocity after the step), as MuJoCo's
    implicitfast does for kv (under Euler the loader applies kv explicitly, as MuJoCo does)."""

    names: list[str]
    time: np.ndarray  # (T,)
    ctrl: np.ndarray  # (T, nu)
    mujoco_force: np.ndarray  # (T, nu)
    sapien_force: np.ndarray  # (T, nu)


@dataclass
class TierReport:
    """A tier's verdict with its numbers; `series` are per-step error series (name -> (T,)) for recording."""

    tier: str
    status: str
    metrics: list[Metric] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    settings: dict = field(default_factory=dict)
    series: dict[str, np.ndarray] = field(default_factory=dict)
    traces: list[Trace] = field(default_factory=list)
    actuators: ActuatorTrace | None = None
    divergence: Divergence | None = None  # the first step SAPIEN left the finite, physical states

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"unknown tier status {self.status!r}")

    def to_dict(self) -> dict:
        out = {
            "tier": self.tier,
            "status": self.status,
            "metrics": [m.to_dict() for m in self.metrics],
            "notes": list(self.notes),
            "settings": self.settings,
        }
        if self.divergence is not None:
            out["divergence"] = self.divergence.to_dict()
        return out


def verdict(
    metrics: list[Metric], chaotic: bool = False, divergence: Divergence | None = None, simulated: bool = True
) -> str:
    """Every tier's status. A simulated tier is diverged when SAPIEN left the finite, physical states or a metric is
    not finite (whatever else holds); fail when a metric is past its tolerance; chaotic when MuJoCo cannot predict
    itself; else pass. A static tier (`simulated=False`) never diverges: an infinite error there, such as a finite
    limit against an infinite one, is a failure of the mapping."""
    if simulated and (divergence is not None or any(not math.isfinite(m.max) for m in metrics)):
        return "diverged"
    if not all(m.passed for m in metrics):
        return "fail"
    return "chaotic" if chaotic else "pass"


def judged(tier: str, metrics: list[Metric], notes: list[str] | None = None, **extra) -> TierReport:
    """A static tier's report, judged by `verdict`."""
    return TierReport(tier, verdict(metrics, simulated=False), metrics, list(notes or []), **extra)


def skipped(tier: str, reason: str) -> TierReport:
    return TierReport(tier, "skipped", notes=[reason])
