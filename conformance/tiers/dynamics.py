"""Tier 5: dynamics without contact under identical generalized-force commands.

(a) one-step error: every k steps MuJoCo's state is copied into SAPIEN, both step once, and the velocity
increment (qacc), velocity and position are compared; (b) open-loop rollouts from qpos0 under zero command,
seeded smooth torques, and PD tracking of a seeded target (torques computed on the MuJoCo run, replayed on
SAPIEN). Every rollout is gated by MuJoCo's own sensitivity to a 1e-6 perturbation."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import chaos, commands, reference, sapien_side
from ..divergence import Divergence, SpeedBound, first_divergence, first_of
from ..report import Metric, TierReport, Trace, metric, skipped, verdict
from ..tolerances import Tolerances
from .rollouts import disable_contacts, is_floating, sapien_rollout, settings_metric, settings_mismatches


def one_step(
    result, ref: mujoco.MjModel, run: reference.Rollout, every: int, bound: SpeedBound
) -> tuple[dict[str, np.ndarray], Divergence | None]:
    """Per sampled step, both simulators from the state SAPIEN holds: |SAPIEN - MuJoCo| of the velocity increment
    / dt, the velocity and the position; and the first sampled step whose SAPIEN state left what MuJoCo's run
    allows."""
    dt = ref.opt.timestep
    qacc, qvel, qpos, states, sampled = [], [], [], [], []
    for t in range(0, run.command.shape[0], every):
        q0, v0 = sapien_side.held_start(result, run.qpos[t], run.qvel[t])
        ref_q1, ref_v1 = reference.step_from(ref, q0, v0, qfrc=run.command[t])
        sapien_side.apply_generalized_force(result, run.command[t])
        result.scene.step()
        q1, v1 = sapien_side.get_state(result)
        qacc.append(np.abs(v1 - ref_v1) / dt)
        qvel.append(np.abs(v1 - ref_v1))
        qpos.append(np.abs(reference.qpos_difference(ref, ref_q1, q1)))
        states.append((q1, v1))
        sampled.append(t + 1)
    sapien_side.clear_command(result, ref.nv)
    found = (
        first_divergence("one-step", [q for q, _ in states], [v for _, v in states], run.qvel, bound, dt, sampled)
        if states
        else None
    )
    return {"qacc": np.array(qacc), "qvel": np.array(qvel), "qpos": np.array(qpos)}, found


def dynamics(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    if model.nv == 0:
        return skipped("dynamics", "the model has no degrees of freedom")
    ref, matched = reference.matched(model, contact=False)
    disable_contacts(result)
    floating = is_floating(model)
    kind = "floating" if floating else "fixed"
    dt = ref.opt.timestep
    steps = tolerances.horizon_steps("dynamics", dt)
    qpos0, qvel0, start = reference.initial_state(model)
    qpos0, qvel0 = sapien_side.held_start(result, qpos0, qvel0)
    limit = tolerances.setting("chaos", "amplification_limit")
    perturbation = tolerances.setting("chaos", "perturbation")
    torque = commands.random_torque(ref, qpos0, steps, seed, tolerances.setting("dynamics", "torque_accel"))
    pd = commands.PDTracking(
        ref,
        qpos0,
        steps,
        seed,
        tolerances.setting("dynamics", "pd_amplitude"),
        tolerances.setting("dynamics", "pd_freq_hz"),
    )
    mismatched = settings_mismatches(result, ref)
    metrics: list[Metric] = [settings_metric(mismatched)]
    notes: list[str] = list(mismatched)
    series: dict[str, np.ndarray] = {}
    traces: list[Trace] = []

    # (a) one-step error along the torque-driven MuJoCo trajectory
    torque_run = reference.rollout(ref, qpos0, qvel0, steps, torque)
    if torque_run.unstable(ref):
        return skipped("dynamics", torque_run.unstable(ref))
    bound = SpeedBound.from_tolerances(tolerances)
    errs, diverged = one_step(result, ref, torque_run, int(tolerances.setting("dynamics", "one_step_every")), bound)
    for name, unit in (("qacc", "rad/s^2 or m/s^2"), ("qvel", "rad/s or m/s"), ("qpos", "rad or m")):
        metrics.append(metric(f"one_step_{name}", errs[name], tolerances[f"dynamics.one_step_{name}_{kind}"], unit))
        series[f"one_step_{name}"] = errs[name].max(axis=1)

    # (b) open-loop rollouts, each judged on the horizon MuJoCo itself can predict
    chaotic = []
    gates = {}
    rows = sapien_side.body_link_rows(result, model.nbody)
    for name, command in (("zero", None), ("torque", torque), ("pd", pd)):
        run = torque_run if name == "torque" else reference.rollout(ref, qpos0, qvel0, steps, command)
        if run.unstable(ref):
            return skipped("dynamics", f"{name} command: {run.unstable(ref)}")
        gate = chaos.gate(ref, run, seed, perturbation, limit)
        sp = sapien_rollout(result, model, qpos0, qvel0, run.command)
        diverged = first_of(diverged, first_divergence(f"rollout {name}", sp.qpos, sp.qvel, run.qvel, bound, dt))
        err = reference.qpos_difference(ref, run.qpos, sp.qpos)
        tolerance = tolerances[f"dynamics.rollout_qpos_{kind}"]
        gate = gate.held(metric("whole", err, tolerance, "rad or m").passed)
        gates[name] = gate.to_dict()
        metrics.append(metric(f"rollout_{name}_qpos", err[: gate.judged_steps + 1], tolerance, "rad or m"))
        series[f"rollout_{name}_qpos"] = np.abs(err).max(axis=1)
        series[f"rollout_{name}_chaos_amplification"] = gate.amplification
        if gate.chaotic:
            chaotic.append(name)
            notes.append(
                f"rollout {name}: MuJoCo amplifies a {perturbation:g} perturbation more than "
                f"{limit:g}x after step {gate.judged_steps} of {steps}; judged on the first "
                f"{gate.judged_steps} steps only"
            )
        traces.append(
            Trace(
                name,
                np.arange(steps + 1) * dt,
                run.qpos,
                sp.qpos,
                err,
                np.vstack([run.command, np.zeros((1, model.nv))]),
                run.body_pose,
                sapien_side.bodies_from_links(sp.link_pose, rows),
                sp.link_pose,
            )
        )
    sapien_side.set_state(result, qpos0, qvel0)
    return TierReport(
        "dynamics",
        verdict(metrics, bool(chaotic), diverged),
        metrics,
        notes,
        settings={
            **matched,
            "steps": steps,
            "base": kind,
            "chaos": gates,
            "start": start,
            "one_step_every": int(tolerances.setting("dynamics", "one_step_every")),
        },
        series=series,
        traces=traces,
        divergence=diverged,
    )
