"""Isolation: a failing dynamics-type tier is run again with the model's known gaps taken out, on both sides.

Each gap is an edit of the model's `MjSpec` (`gaps.py`: frictionloss zeroed, equalities or limits disabled, fluid
off, the timestep halved; a floating root welded or tendon springs zeroed, only where an expectation claims it);
MuJoCo compiles the edited spec and the loader loads the same spec, so both simulators see the same change. The tier
then runs as usual. Its numbers, gap by gap and all gaps together, say which gap the failure comes from: a model
whose actuators are mapped right passes once the gaps PhysX cannot express are out, and a mapping error (a wrong kp,
a flipped gear) survives every edit.
The half timestep separates integrator differences from force errors: one-step velocity errors from a force
mismatch halve with dt (order 1), an integration difference shrinks four times (order 2). Order 2 also fits a
force error that is itself O(dt): the velocity-product drift PhysX's slide drives measured
(loader/runtime/slides.py) was first read here as an integration difference, so an order-2 residual is a lead, not a
verdict.
A manifest expectation may claim `passes_without = [...]`: the run checks that the tier passes with exactly
those gaps out, so the reason written there is measured on every run.
"""

from __future__ import annotations

import math

import mujoco

from .gaps import edited_spec, present_gaps
from .session import quiet_load

ISOLATED_TIERS = ("dynamics", "actuated", "maniskill_tensor")


def _load(spec: mujoco.MjSpec):
    result = quiet_load(spec)
    result.disable_actuators()
    return result


def run_without(path: str, tier: str, gaps: tuple[str, ...], seed: int, tolerances) -> dict:
    """The tier on the model with `gaps` removed on both sides: outcome and metrics (or the error it raised)."""
    from .tiers import TIERS

    entry: dict = {"without": list(gaps)}
    try:
        result = _load(edited_spec(path, gaps))
        report = TIERS[tier](result, result.model, seed, tolerances)
    except Exception as exc:  # noqa: BLE001 - a failed isolation run is reported, it does not stop the model
        return {**entry, "outcome": "error", "reason": f"{type(exc).__name__}: {exc}", "metrics": []}
    return {
        **entry,
        "outcome": report.status,
        "metrics": [
            {"name": m.name, "max": m.max, "tolerance": m.tolerance}
            for m in report.metrics
            if m.name != "settings_mismatches"
        ],
    }


def isolate(
    path: str, model: mujoco.MjModel, tier: str, seed: int, tolerances, claimed: tuple[tuple[str, ...], ...] = ()
) -> list[dict]:
    """Runs of `tier` without each present gap, without all of them, and without each claimed combination."""
    gaps = present_gaps(model)
    physical = tuple(g for g in gaps if g != "half_timestep")
    combos = [(g,) for g in gaps]
    for combo in (physical, tuple(gaps), *claimed):
        if combo and combo not in combos:
            combos.append(combo)
    return [run_without(path, tier, combo, seed, tolerances) for combo in combos]


def order_in_timestep(full_dt_error: float, half_dt_error: float) -> float | None:
    """Observed order p of a one-step velocity error in the timestep: error(dt) / error(dt/2) = 2^p."""
    if not (full_dt_error > 0 and half_dt_error > 0):
        return None
    return math.log2(full_dt_error / half_dt_error)


def claim_holds(runs: list[dict], claimed: tuple[str, ...]) -> bool:
    """Whether the tier passed with exactly the claimed gaps removed."""
    return any(set(r["without"]) == set(claimed) and r["outcome"] == "pass" for r in runs)
