"""Tier 6: dynamics with contact, judged by the settled pose and step by step.

Both sides start at qpos0 with no command and settle under gravity. Compared: the mean height of every
floating root over the last quarter of the horizon (rest height), every body's mean position over that
window (final-pose band), and the joint positions at every step over the horizon MuJoCo can predict
(`rollout_qpos`). MuJoCo's own spread under a perturbation of the start decides whether the outcome is
predictable at all (otherwise: chaotic)."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import chaos, reference, sapien_side
from ..divergence import SpeedBound, first_divergence
from ..report import TierReport, metric, skipped
from ..tolerances import Tolerances
from .rollouts import (
    carried,
    compare_settled,
    sapien_rollout,
    settle_trace,
    settled_verdict,
    trajectory,
    untouched,
)


def contact(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    if model.nv == 0:
        return skipped("contact", "the model has no degrees of freedom")
    if reference.contacts_disabled(model):
        return skipped("contact", "the model disables contact (contact or constraint flag)")
    if not carried(result, model):
        return skipped("contact", "no MuJoCo body is carried by an articulation link")
    ref, matched = reference.matched(model, contact=True)
    dt = ref.opt.timestep
    steps = tolerances.horizon_steps("contact", dt)
    qpos0, qvel0, start = reference.initial_state(model)
    run = reference.rollout(ref, qpos0, qvel0, steps, None)
    if run.unstable(ref):
        return skipped("contact", run.unstable(ref))
    other = reference.rollout(
        ref, chaos.perturbed(ref, qpos0, tolerances.setting("contact", "perturbation"), seed), qvel0, steps, None
    )
    sp = sapien_rollout(result, model, qpos0, qvel0, np.zeros((steps, model.nv)))
    diverged = first_divergence("settle", sp.qpos, sp.qvel, run.qvel, SpeedBound.from_tolerances(tolerances), dt)
    sapien_side.set_state(result, qpos0, qvel0)
    poses = compare_settled(result, model, run.body_pose, other.body_pose, sp)
    judged = trajectory(ref, run, sp, seed, tolerances, "contact.rollout_qpos")
    metrics = [
        metric("final_pose_band", poses.band, tolerances["contact.final_pose_band"], "m"),
        metric("rest_height", poses.rest, tolerances["contact.rest_height"], "m"),
        judged.metric,
    ]
    spread = poses.spread
    status, notes = settled_verdict(metrics, spread, tolerances["contact.final_pose_band"], tolerances, diverged)
    notes += judged.notes + untouched(run)
    return TierReport(
        "contact",
        status,
        metrics,
        notes,
        divergence=diverged,
        settings={
            **matched,
            "steps": steps,
            "start": start,
            "chaos": judged.gate.to_dict(),
            "mujoco_self_spread": float(spread.max(initial=0.0)),
        },
        series={"final_pose_band_per_step": poses.series},  # the largest body distance each step
        traces=[settle_trace(result, ref, run, sp, "contact")],
    )
