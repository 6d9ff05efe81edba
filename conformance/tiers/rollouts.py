"""What the simulated tiers share: the SAPIEN side of a rollout, the scene checks before one, and the settled-pose
comparison the contact tiers judge by."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from loader.model.joints import mujoco_coordinates

from .. import chaos, reference, sapien_side
from ..report import Metric, Trace, metric, verdict


def is_floating(model: mujoco.MjModel) -> bool:
    return bool((model.jnt_type == mujoco.mjtJoint.mjJNT_FREE).any())


def floating_roots(model: mujoco.MjModel) -> list[int]:
    return [int(model.jnt_bodyid[j]) for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]


def carried(result, model: mujoco.MjModel) -> list[int]:
    """The MuJoCo bodies an articulation link carries (what a settled pose is compared over)."""
    return [b for b in range(1, model.nbody) if sapien_side.body_link(result, b) is not None]


def disable_contacts(result) -> None:
    """Contacts off for the contact-free tiers; they stay off (later tiers run contact-free or are ordered before)."""
    result.set_contacts(False)


def sapien_rollout(result, model: mujoco.MjModel, qpos0, qvel0, command: np.ndarray) -> sapien_side.Run:
    """Replay `command` (steps, nv), a generalized force per step, on SAPIEN from (qpos0, qvel0)."""
    run = sapien_side.rollout(
        result, qpos0, qvel0, command.shape[0], lambda t, q, v: sapien_side.apply_generalized_force(result, command[t])
    )
    sapien_side.clear_command(result, model.nv)
    return run


def settle_trace(result, ref: mujoco.MjModel, run, sp: sapien_side.Run, name: str) -> Trace:
    """A contact rollout as a `Trace` for the recording (no generalized command: any ctrl is in the actuators)."""
    steps = run.qpos.shape[0]
    return Trace(
        name,
        np.arange(steps) * ref.opt.timestep,
        run.qpos,
        sp.qpos,
        reference.qpos_difference(ref, run.qpos, sp.qpos),
        np.zeros((steps, ref.nv)),
        run.body_pose,
        sapien_side.bodies_from_links(sp.link_pose, sapien_side.body_link_rows(result, ref.nbody)),
        sp.link_pose,
        contact=True,
    )


def settings_mismatches(result, ref: mujoco.MjModel) -> list[str]:
    """Timestep, gravity and solver of the SAPIEN scene (its PhysX system's own configuration) against the MuJoCo
    reference."""
    config = result.scene.physx_system.config
    gravity = np.zeros(3) if ref.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY else ref.opt.gravity
    out = []
    if abs(result.scene.timestep - ref.opt.timestep) > 1e-6 * ref.opt.timestep:  # SAPIEN stores float32
        out.append(f"timestep {result.scene.timestep} in SAPIEN, {ref.opt.timestep} in MuJoCo")
    if np.max(np.abs(np.asarray(config.gravity) - gravity)) > 1e-6:
        out.append(f"gravity {list(config.gravity)} in SAPIEN, {list(gravity)} in MuJoCo")
    if config.enable_tgs and not mujoco_coordinates(ref):
        out.append("SAPIEN uses TGS and the model's ball joints keep PhysX's drives, which TGS steps unlike MuJoCo")
    return out


def settings_metric(mismatched: list[str]) -> Metric:
    """The count of scene settings that differ from MuJoCo's, judged against zero."""
    return Metric("settings_mismatches", float(len(mismatched)), float(len(mismatched)), 0.0, "count", 3)


def settled(poses: np.ndarray) -> np.ndarray:
    """Mean body positions (nbody, 3) over the last quarter of a rollout."""
    tail = max(1, poses.shape[0] // 4)
    return poses[-tail:, :, :3].mean(axis=0)  # NaN rows (bodies without a link) stay NaN


@dataclass
class Settled:
    """Both sides' settled poses compared: per body the distance of SAPIEN's from MuJoCo's (`band`), per floating
    root the height difference (`rest`), MuJoCo's own distance under a perturbed start (`spread`), and the
    per-step largest body distance (`series`)."""

    band: np.ndarray
    rest: np.ndarray
    spread: np.ndarray
    series: np.ndarray


def compare_settled(
    result, model: mujoco.MjModel, mujoco_poses: np.ndarray, perturbed_poses: np.ndarray, run: sapien_side.Run
) -> Settled:
    """MuJoCo's body poses (T, nbody, 7), those of MuJoCo's perturbed run, and SAPIEN's run, compared over the
    bodies SAPIEN carries on a link."""
    poses = sapien_side.bodies_from_links(run.link_pose, sapien_side.body_link_rows(result, model.nbody))
    bodies = carried(result, model)
    mj_final, sp_final, own = settled(mujoco_poses), settled(poses), settled(perturbed_poses)
    roots = floating_roots(model)
    return Settled(
        band=np.linalg.norm(sp_final[bodies] - mj_final[bodies], axis=1),
        rest=np.abs(sp_final[roots, 2] - mj_final[roots, 2]),
        spread=np.linalg.norm(own[bodies] - mj_final[bodies], axis=1),
        series=np.nanmax(np.linalg.norm(poses[:, bodies, :3] - mujoco_poses[:, bodies, :3], axis=2), axis=1),
    )


@dataclass
class Trajectory:
    """A rollout judged step by step (`trajectory`): its metric, MuJoCo's own gate, the gate's note (empty where
    the whole horizon is judged) and the per-step errors (steps + 1, nv)."""

    metric: Metric
    gate: chaos.ChaosGate
    notes: list[str]
    errors: np.ndarray


def trajectory(ref: mujoco.MjModel, run, sp: sapien_side.Run, seed: int, tolerances, key: str) -> Trajectory:
    """A rollout judged step by step where MuJoCo can predict itself: the largest |qpos| difference from MuJoCo's
    over the horizon MuJoCo's own 1e-6 gate keeps (`chaos.gate`, all of it where SAPIEN agrees throughout), against
    the tolerance `key`, less what float32 cannot resolve: the actuated tier's rollout and the contact tiers' settle
    (tests/test_tiers_contact.py::test_a_contact_rollout_is_judged_step_by_step_where_mujoco_predicts_itself)."""
    gate = chaos.gate(
        ref, run, seed, tolerances.setting("chaos", "perturbation"), tolerances.setting("chaos", "amplification_limit")
    )
    err = reference.qpos_difference(ref, run.qpos, sp.qpos)
    # float32 holds SAPIEN's coordinates: what it cannot resolve at the size each has reached is not judged
    floor = float(tolerances.setting("actuated", "float32_relative")) * reference.position_scale(ref, run.qpos)
    tolerance = tolerances[key]
    gate = gate.held(metric("whole", err, tolerance, "rad or m", floor=floor).passed)
    judged = gate.judged_steps + 1
    notes = []
    if gate.chaotic:
        notes.append(
            f"MuJoCo amplifies a {gate.perturbation:g} perturbation more than {gate.limit:g}x after step "
            f"{gate.judged_steps} of {gate.steps}; the rollout is judged on the first {gate.judged_steps} steps"
        )
    return Trajectory(
        metric("rollout_qpos", err[:judged], tolerance, "rad or m", floor=floor[:judged]), gate, notes, err
    )


UNTOUCHED = "nothing touches in MuJoCo's run (no contact at any step): the settle was judged without a contact"


def untouched(run) -> list[str]:
    """The note of a contact tier whose MuJoCo run makes no contact: its pass says only that SAPIEN, too, settled
    without one (tests/test_tiers_contact.py::test_a_contact_tier_says_when_nothing_touched)."""
    return [UNTOUCHED] if run.contacts is not None and not run.contacts.any() else []


def settled_verdict(
    metrics: list[Metric], spread: np.ndarray, band: float, tolerances, divergence
) -> tuple[str, list[str]]:
    """The contact tiers' one rule for a settled pose, and its note. MuJoCo's own spread (its settled bodies moved
    by a perturbation of the start, `contact.perturbation`) decides first: at `contact.spread_fraction` of the
    final-pose band (`band`) or more, the outcome is `chaotic` whatever SAPIEN's deviation, since MuJoCo cannot
    predict itself there. Below it, a metric past its tolerance is a `fail`, and such a deviation then exceeds
    MuJoCo's own spread by at least 1 / spread_fraction; a divergence outranks both
    (tests/test_tiers_contact.py::test_a_settled_verdict_is_chaotic_by_mujocos_spread_and_fails_only_beyond_it)."""
    fraction, size = tolerances.setting("contact", "spread_fraction"), tolerances.setting("contact", "perturbation")
    worst = float(spread.max(initial=0.0))
    status = verdict(metrics, False, divergence)
    deviation = next((m.max for m in metrics if m.name == "final_pose_band"), 0.0)
    if worst >= fraction * band and status != "diverged":
        why = (
            f"MuJoCo's own settled pose moves {worst:.3g} m under a {size:g} perturbation of the start, at least "
            f"{fraction:g} of the {band:g} m band: chaotic whatever SAPIEN's deviation ({deviation:.3g} m)"
        )
        return "chaotic", [why]
    if status == "fail":
        why = (
            f"SAPIEN's settled pose is {deviation:.3g} m from MuJoCo's, where MuJoCo's own spread is {worst:.3g} m "
            f"(below {fraction:g} of the band)"
        )
        return status, [why]
    return status, []
