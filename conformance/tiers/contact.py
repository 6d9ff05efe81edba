"""Tier 6: dynamics with contact, judged statistically (rest heights, final-pose bands), never step by step.

Both sides start at qpos0 with no command and settle under gravity. Compared: the mean height of every
floating root over the last quarter of the horizon (rest height), and every body's mean position over that
window (final-pose band). MuJoCo's own spread under a perturbation of the start decides whether the outcome
is predictable at all (otherwise: chaotic)."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import chaos, reference, sapien_side
from ..divergence import SpeedBound, first_divergence
from ..report import TierReport, metric, skipped, verdict
from ..tolerances import Tolerances
from .dynamics import sapien_rollout


def settled(poses: np.ndarray) -> np.ndarray:
    """Mean body positions (nbody, 3) over the last quarter of a rollout."""
    tail = max(1, poses.shape[0] // 4)
    return poses[-tail:, :, :3].mean(axis=0)  # NaN rows (bodies without a link) stay NaN


def floating_roots(model: mujoco.MjModel) -> list[int]:
    return [int(model.jnt_bodyid[j]) for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]


def contact(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    if model.nv == 0:
        return skipped("contact", "the model has no degrees of freedom")
    if reference.contacts_disabled(model):
        return skipped("contact", "the model disables contact (contact or constraint flag)")
    ref, matched = reference.matched(model, contact=True)
    dt = ref.opt.timestep
    steps = tolerances.horizon_steps("contact", dt)
    qpos0, qvel0, start = reference.initial_state(model)
    run = reference.rollout(ref, qpos0, qvel0, steps, None)
    if run.unstable(ref):
        return skipped("contact", run.unstable(ref))
    # MuJoCo against itself: the 1e-6 gate of every rollout (recorded; contact is judged by bands, below)
    gate = chaos.gate(ref, run, seed, tolerances.setting("chaos", "perturbation"),
                      tolerances.setting("chaos", "amplification_limit"))
    other = reference.rollout(ref, chaos.perturbed(ref, qpos0, tolerances.setting("contact", "perturbation"), seed),
                              qvel0, steps, None)
    sp = sapien_rollout(result, model, qpos0, qvel0, np.zeros((steps, model.nv)))
    diverged = first_divergence("settle", sp.qpos, sp.qvel, run.qvel, SpeedBound.from_tolerances(tolerances), dt)
    sp_poses = sapien_side.bodies_from_links(sp.link_pose, sapien_side.body_link_rows(result, model.nbody))
    sapien_side.set_state(result, qpos0, qvel0)
    bodies = [b for b in range(1, model.nbody) if sapien_side.body_link(result, b) is not None]
    mj_final, sp_final, own = settled(run.body_pose), settled(sp_poses), settled(other.body_pose)
    band = np.linalg.norm(sp_final[bodies] - mj_final[bodies], axis=1)
    spread = np.linalg.norm(own[bodies] - mj_final[bodies], axis=1)
    roots = floating_roots(model)
    rest = np.abs(sp_final[roots, 2] - mj_final[roots, 2])
    metrics = [
        metric("final_pose_band", band, tolerances["contact.final_pose_band"], "m"),
        metric("rest_height", rest, tolerances["contact.rest_height"], "m"),
    ]
    notes = []
    chaotic = spread.size and spread.max() > tolerances.setting("contact", "spread_fraction") * \
        tolerances["contact.final_pose_band"]
    if chaotic:
        notes.append(f"MuJoCo's own settled pose moves {spread.max():.3g} m under a "
                     f"{tolerances.setting('contact', 'perturbation'):g} perturbation: outcome not predictable")
    return TierReport("contact", verdict(metrics, bool(chaotic), diverged), metrics, notes, divergence=diverged,
                      settings={**matched, "steps": steps, "start": start, "chaos": gate.to_dict(), "mujoco_self_spread": float(spread.max(initial=0.0))},
                      series={"final_pose_band": np.nanmax(np.linalg.norm(
                          sp_poses[:, bodies, :3] - run.body_pose[:, bodies, :3], axis=2), axis=1)})
