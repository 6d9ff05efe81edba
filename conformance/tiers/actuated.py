"""Tier 7: both simulators receive the same MuJoCo `ctrl` sequence every step (the loader's actuator mapping).

`actuated_contact` (run first): ctrl held at the keyframe's (or at the one that holds the start), then a step
to a seeded target, contact on; judged statistically like `contact` (final-pose band, rest height of floating
roots; chaotic when MuJoCo's own settled pose moves under a perturbation of the start).
`actuated` (contact-free): the hold, the step, then smooth random targets inside ctrlrange; judged like
`dynamics`: a one-step velocity error along MuJoCo's trajectory and the open-loop rollout error on the horizon
MuJoCo's own 1e-6 sensitivity allows.

MuJoCo keeps actuation on (a reference copy separate from the dynamics tiers') and integrates with the model's
own integrator, or the one PhysX can follow (RK4 -> Euler, implicit -> implicitfast; recorded in the settings):
the loader applies kv implicitly or explicitly as that integrator does. SAPIEN's actuators
are enabled for the tier (`result.disable_actuators(False)`) and disabled again after, and the state is put back
at the start; contacts stay off after `actuated`, as after `dynamics`.
Contact-free, deviations from the held ctrl shrink by halves until no joint reaches a limit in MuJoCo (soft
there, hard in PhysX); what scaling cannot avoid is noted as a known gap. Saturated actuators are judged as they
are: the loader clamps forcerange and actuatorfrcrange as MuJoCo does (steps on a bound are counted in the
settings).
A model with an unmapped actuator is skipped with its name, unless the manifest sets
`actuated.unmapped = "remove"`: then the unmapped actuators get zero gain and bias in MuJoCo too (noted), as
they apply nothing in SAPIEN."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, fields

import mujoco
import numpy as np

from loader.model.mj import fixed_tendon_terms
from loader.plan.geom import collides
from loader.runtime.dof_step import clear_qf
from loader.runtime.tendons import TendonPaths
from loader.runtime.transmissions import MomentPaths, MuscleLaws

from .. import chaos, commands, reference, sapien_side
from ..divergence import Divergence, SpeedBound, first_divergence, first_of
from ..report import ActuatorTrace, Metric, TierReport, Trace, metric, skipped, verdict
from ..tolerances import Tolerances
from .rollouts import (
    carried,
    compare_settled,
    disable_contacts,
    is_floating,
    settings_metric,
    settings_mismatches,
    settle_trace,
    settled_verdict,
    trajectory,
    untouched,
)


def unmapped(result) -> list[int]:
    """Indices of the actuators the loader did not map."""
    return [a for a, actuator in enumerate(result.actuators) if not actuator.mapped]


def unmapped_reason(result, model: mujoco.MjModel, tier: str, tolerances: Tolerances) -> TierReport | None:
    """A skip report when the tier has nothing to judge, or when an actuator is not mapped and the manifest
    does not ask (setting `actuated.unmapped = "remove"`) to take the unmapped ones out of MuJoCo too."""
    if model.nv == 0:
        return skipped(tier, "the model has no degrees of freedom")
    if model.nu == 0:
        return skipped(tier, "the model has no actuators")
    if model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION):
        return skipped(tier, "the model disables actuation (<flag actuation='disable'/>)")
    names = [result.actuators[a].name for a in unmapped(result)]
    if names and tolerances.setting("actuated", "unmapped") != "remove":
        return skipped(tier, f"{len(names)} of {model.nu} actuators not mapped by the loader: " + ", ".join(names))
    return None


def reference_model(result, model: mujoco.MjModel, contact: bool) -> tuple[mujoco.MjModel, dict, list[str]]:
    """MuJoCo's copy with actuation on; unmapped actuators (only when the manifest asks) get zero gain and bias,
    so that they apply no force in MuJoCo either. Returns the copy, its settings and notes."""
    ref, matched = reference.matched(model, contact=contact, actuation=True)
    removed = unmapped(result)
    for a in removed:
        ref.actuator_gainprm[a] = 0.0
        ref.actuator_biasprm[a] = 0.0
    notes = (
        [
            "unmapped actuators taken out of MuJoCo as well (manifest setting): "
            + ", ".join(result.actuators[a].name for a in removed)
        ]
        if removed
        else []
    )
    return ref, {**matched, "actuators_removed": [result.actuators[a].name for a in removed]}, notes


@contextmanager
def actuated_scene(result, qpos0, qvel0, contacts: bool):
    """SAPIEN actuators on (and contacts off unless asked) inside; on exit actuators off, the start state
    restored and no command left in `qf` (where `disable_actuators`' last `set_ctrl` wrote MuJoCo's whole law).
    Contacts stay off after a contact-free run, as after `dynamics`: turning collision groups back on once PhysX
    has stepped without them crashes PhysX (segmentation fault on the next step, manipulator)."""
    result.disable_actuators(False)
    if not contacts:
        disable_contacts(result)
    try:
        yield
    finally:
        result.disable_actuators(True)
        sapien_side.set_state(result, qpos0, qvel0)
        clear_qf(result.articulations)


class ForceLaw:
    """Actuator-space force of every actuator from a MuJoCo-layout state, with the loader's parameters
    (`result.model` gains and biases, `result.actuators` gears and tendon terms): see `report.ActuatorTrace`.
    Its input is what the gain multiplies: ctrl, or SAPIEN's activation for actuators with dynamics."""

    def __init__(self, result):
        model = result.model
        self.gain = model.actuator_gainprm[:, 0].copy()
        affine = model.actuator_biastype == int(mujoco.mjtBias.mjBIAS_AFFINE)
        self.bias = np.where(affine[:, None], model.actuator_biasprm[:, :3], 0.0)
        self.lo = np.where(model.actuator_forcelimited, model.actuator_forcerange[:, 0], -np.inf)
        self.hi = np.where(model.actuator_forcelimited, model.actuator_forcerange[:, 1], np.inf)
        self.length = np.zeros((model.nu, model.nq))  # actuator length = length @ qpos
        self.speed = np.zeros((model.nu, model.nv))
        self.spatial: list[tuple[int, int, float]] = []  # (actuator, tendon, gear): lengths from MuJoCo's path
        moments = []  # actuators whose length and moment MuJoCo's transmission gives
        for a, actuator in enumerate(result.actuators):
            if not actuator.mapped:  # SAPIEN applies nothing for it
                self.gain[a], self.bias[a] = 0.0, 0.0
                continue
            if actuator.moment:
                moments.append(a)
                continue
            if actuator.joint is not None:
                joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, actuator.joint)
                terms = [(joint, 1.0)] if joint >= 0 else []
            elif actuator.tendon is not None:
                tendon = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, actuator.tendon)
                terms = fixed_tendon_terms(model, tendon)
                if not terms:
                    self.spatial.append((a, tendon, actuator.gear))
            else:
                terms = []
            for joint, coefficient in terms:
                self.length[a, model.jnt_qposadr[joint]] += actuator.gear * coefficient
                self.speed[a, model.jnt_dofadr[joint]] += actuator.gear * coefficient

        self.paths = TendonPaths(model, result.mapping, [t for _, t, _ in self.spatial]) if self.spatial else None
        self.moments = MomentPaths(model, result.mapping, moments) if moments else None
        if self.moments is not None:  # a body transmission reads MuJoCo's contacts only while SAPIEN has them
            self.moments.contacts(sapien_side.contacts_enabled(result))
        muscles = [a for a in moments if result.actuators[a].muscle]
        self.muscles = MuscleLaws(model, muscles) if muscles else None

    def __call__(self, ctrl, qpos, qvel) -> np.ndarray:
        length, speed = self.length @ qpos, self.speed @ qvel
        if self.paths is not None:  # spatial tendons: MuJoCo's length and Jacobian at this pose
            lengths, jacobian = self.paths.measure(qpos)
            for row, (a, _, gear) in enumerate(self.spatial):
                length[a] = gear * lengths[row]
                speed[a] = gear * (jacobian[row] @ qvel[self.paths.dofs])
        if self.moments is not None:  # site, slider-crank, body and free-joint transmissions: MuJoCo's at this pose
            lengths, moment = self.moments.measure(qpos)
            length[self.moments.tendons] = lengths
            speed[self.moments.tendons] = moment @ qvel[self.moments.dofs]
        force = self.gain * ctrl + self.bias[:, 0] + self.bias[:, 1] * length + self.bias[:, 2] * speed
        if self.muscles is not None:  # MuJoCo's muscle curves of the activation, length and rate
            a = self.muscles.indices
            force[a] = self.muscles.force(np.asarray(ctrl)[a], length[a], speed[a])
        return np.clip(force, self.lo, self.hi)


def sapien_ctrl_rollout(result, model: mujoco.MjModel, qpos0, qvel0, ctrl: np.ndarray) -> sapien_side.Run:
    """Replay `ctrl` (steps, nu) on SAPIEN through `result.set_ctrl` from (qpos0, qvel0), with the actuator force
    law evaluated on SAPIEN's state before each step (`Run.force`, (T, nu))."""
    law = ForceLaw(result)
    clipped = commands.clip_ctrl(model, ctrl)
    force = np.zeros((ctrl.shape[0], model.nu))
    activation = result.controller.activation

    def before_step(t: int, q: np.ndarray, v: np.ndarray) -> None:
        force[t] = law(clipped[t] if activation is None else activation.inputs(clipped[t]), q, v)
        result.set_ctrl(ctrl[t])

    run = sapien_side.rollout(result, qpos0, qvel0, ctrl.shape[0], before_step)
    run.force = force
    return run


def one_step_qvel(
    result,
    ref: mujoco.MjModel,
    run: reference.Rollout,
    every: int,
    bound: SpeedBound,
    dt: float,
    float32_relative: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, Divergence | None]:
    """Every `every` steps: MuJoCo's state into SAPIEN, both from the state SAPIEN holds (float32), the same ctrl,
    one step; |SAPIEN - MuJoCo| velocity,
    less what float32 cannot resolve: `float32_relative` times the larger speed before or after the step (SAPIEN
    holds the state and integrates in float32; a motor spinning a light body up to hundreds of rad/s leaves
    1e-5 rad/s of rounding). Also the first sampled step whose SAPIEN state left what MuJoCo's run allows."""
    out, floors, states, sampled = [], [], [], []
    for t in range(0, run.ctrl.shape[0], every):
        q0, v0 = sapien_side.held_start(result, run.qpos[t], run.qvel[t], run.act[t])
        _, ref_v1 = reference.step_from(ref, q0, v0, act=run.act[t], ctrl=run.ctrl[t])
        result.set_ctrl(run.ctrl[t])
        result.scene.step()
        floors.append(float32_relative * np.maximum(np.abs(run.qvel[t]), np.abs(run.qvel[t + 1])))
        states.append(sapien_side.get_state(result))
        sampled.append(t + 1)
        out.append(np.abs(states[-1][1] - ref_v1))
    found = (
        first_divergence("one-step", [q for q, _ in states], [v for _, v in states], run.qvel, bound, dt, sampled)
        if states
        else None
    )
    return np.array(out), np.array(floors), found


def saturated_steps(model: mujoco.MjModel, force: np.ndarray) -> int:
    """Steps at which some force-limited actuator sits on its forcerange bound in MuJoCo."""
    limited = model.actuator_forcelimited.astype(bool)
    if not limited.any():
        return 0
    lo, hi = model.actuator_forcerange[limited].T
    f = force[:, limited]
    tight = 1e-9 * np.maximum(1.0, np.abs(model.actuator_forcerange[limited]).max(axis=1))
    return int(np.any((f <= lo + tight) | (f >= hi - tight), axis=1).sum())


def limit_steps(model: mujoco.MjModel, qpos: np.ndarray) -> int:
    """Steps at which some limited hinge or slide is at or past its range in MuJoCo (soft there, hard in PhysX)."""
    hit = np.zeros(qpos.shape[0], dtype=bool)
    for j, adr, lo, hi in reference.limited_dofs(model):
        margin = float(model.jnt_margin[j])
        hit |= (qpos[:, adr] <= lo + margin) | (qpos[:, adr] >= hi - margin)
    return int(hit.sum())


def gentle_run(
    ref: mujoco.MjModel, qpos0, qvel0, steps: int, seed: int, tolerances: Tolerances, smooth: bool
) -> tuple[reference.Rollout, float, dict[str, int]]:
    """The MuJoCo run under the seeded ctrl, its deviations from the held ctrl halved (at most `max_halvings`
    times) until, for the contact-free run (`smooth`), no joint reaches a limit (with contact, bodies land and fold
    into their limits whatever the ctrl): there MuJoCo's soft and PhysX's hard limits part for reasons that are not
    the actuators'. Returns the run, the scale used and the steps with a forcerange bound reached / at a limit."""

    def s(name: str):
        return tolerances.setting("actuated", name)

    hold = commands.hold_ctrl(ref, qpos0, qvel0)
    phases = (s("hold_fraction"), s("step_until") if smooth else 1.0)
    scale = 1.0
    for _ in range(int(s("max_halvings")) + 1):
        ctrl = commands.ctrl_sequence(ref, hold, steps, seed, s("step_fraction"), s("smooth_fraction"), phases, scale)
        run = reference.rollout(ref, qpos0, qvel0, steps, None, ctrl)
        left = {"saturated": saturated_steps(ref, run.actuator_force), "at_limit": limit_steps(ref, run.qpos)}
        if not (smooth and left["at_limit"]):
            break
        scale /= 2
    return run, scale, left


def _ctrl_notes(scale: float, left: dict[str, int], steps: int, smooth: bool = True) -> list[str]:
    notes = []
    if scale < 1.0:
        notes.append(f"ctrl deviations scaled by {scale:g} so that no joint reaches a limit in MuJoCo")
    if left["saturated"]:
        notes.append(
            f"an actuator sits on its forcerange on {left['saturated']} of {steps} steps (clamped on both sides)"
        )
    if left["at_limit"] and smooth:
        notes.append(
            f"a joint is at its limit in MuJoCo in {left['at_limit']} of the run's {steps + 1} states (its start "
            "and each step's end) even at the held ctrl (its limit rows are MuJoCo's own on both sides)"
        )
    return notes


@dataclass
class ReferenceRun:
    """MuJoCo's side of an actuated tier: its model copy, settings and notes, the start state and the run under
    the seeded ctrl (with the ctrl scale used and the steps on a force bound or at a limit)."""

    ref: mujoco.MjModel
    matched: dict
    removal: list[str]
    steps: int
    qpos0: np.ndarray
    qvel0: np.ndarray
    start: str
    run: reference.Rollout
    scale: float
    left: dict[str, int]

    def __iter__(self):
        return (getattr(self, f.name) for f in fields(self))


def reference_run(
    result, model: mujoco.MjModel, seed: int, tolerances: Tolerances, tier: str, contact: bool
) -> ReferenceRun | TierReport:
    """MuJoCo's run for `tier`, or the skip report when there is nothing to judge."""
    skip = unmapped_reason(result, model, tier, tolerances)
    if skip is not None:
        return skip
    if contact and reference.contacts_disabled(model):
        return skipped(tier, "the model disables contact (contact or constraint flag)")
    if contact and not carried(result, model):
        return skipped(tier, "no MuJoCo body is carried by an articulation link")
    if contact and not any(collides(model, g) for g in range(model.ngeom)):
        return skipped(tier, "no geom can make a contact (every contype and conaffinity is 0, and no <pair>)")
    if contact and not sapien_side.contacts_enabled(result):
        return skipped(tier, "the SAPIEN scene has its contacts turned off (run before dynamics)")
    ref, matched, removal = reference_model(result, model, contact=contact)
    steps = tolerances.horizon_steps(tier, ref.opt.timestep)
    qpos0, qvel0, start = reference.initial_state(model)
    if not contact:
        qpos0, qvel0 = sapien_side.held_start(result, qpos0, qvel0)
    run, scale, left = gentle_run(ref, qpos0, qvel0, steps, seed, tolerances, smooth=not contact)
    if run.unstable(ref):
        return skipped(tier, run.unstable(ref))
    return ReferenceRun(ref, matched, removal, steps, qpos0, qvel0, start, run, scale, left)


def actuated(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    mj_run = reference_run(result, model, seed, tolerances, "actuated", contact=False)
    if isinstance(mj_run, TierReport):
        return mj_run
    ref, matched, removal, steps, qpos0, qvel0, start, run, scale, left = mj_run
    kind = "floating" if is_floating(model) else "fixed"
    dt = ref.opt.timestep
    every = int(tolerances.setting("actuated", "one_step_every"))
    bound = SpeedBound.from_tolerances(tolerances)
    mismatched = settings_mismatches(result, ref)
    with actuated_scene(result, qpos0, qvel0, contacts=False):
        one_step, one_step_floor, diverged = one_step_qvel(
            result, ref, run, every, bound, dt, float(tolerances.setting("actuated", "float32_relative"))
        )
        sp = sapien_ctrl_rollout(result, model, qpos0, qvel0, run.ctrl)
    diverged = first_of(diverged, first_divergence("rollout", sp.qpos, sp.qvel, run.qvel, bound, dt))
    judged = trajectory(ref, run, sp, seed, tolerances, f"actuated.rollout_qpos_{kind}")
    gate, err = judged.gate, judged.errors
    metrics: list[Metric] = [
        settings_metric(mismatched),
        metric(
            "one_step_qvel",
            one_step,
            tolerances[f"actuated.one_step_qvel_{kind}"],
            "rad/s or m/s",
            floor=one_step_floor,
        ),
        judged.metric,
    ]
    notes = removal + list(mismatched) + _ctrl_notes(scale, left, steps) + judged.notes
    rows = sapien_side.body_link_rows(result, model.nbody)
    time = np.arange(steps + 1) * dt
    trace = Trace(
        "actuated",
        time,
        run.qpos,
        sp.qpos,
        err,
        np.zeros((steps + 1, model.nv)),
        run.body_pose,
        sapien_side.bodies_from_links(sp.link_pose, rows),
        sp.link_pose,
    )
    actuators = ActuatorTrace(
        [a.name for a in result.actuators], time[:-1], commands.clip_ctrl(ref, run.ctrl), run.actuator_force, sp.force
    )
    return TierReport(
        "actuated",
        verdict(metrics, gate.chaotic, diverged),
        metrics,
        notes,
        divergence=diverged,
        settings={
            **matched,
            "steps": steps,
            "base": kind,
            "start": start,
            "chaos": gate.to_dict(),
            "ctrl_scale": scale,
            "saturated_steps": left["saturated"],
            "limit_steps": left["at_limit"],
            "one_step_every": every,
        },
        series={
            "rollout_qpos": np.abs(err).max(axis=1),
            "chaos_amplification": gate.amplification,
            "one_step_qvel": one_step.max(axis=1) if one_step.size else one_step,
        },
        traces=[trace],
        actuators=actuators,
    )


def actuated_contact(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    mj_run = reference_run(result, model, seed, tolerances, "actuated_contact", contact=True)
    if isinstance(mj_run, TierReport):
        return mj_run
    ref, matched, removal, steps, qpos0, qvel0, start, run, scale, left = mj_run
    dt = ref.opt.timestep
    size = tolerances.setting("contact", "perturbation")
    other = reference.rollout(ref, chaos.perturbed(ref, qpos0, size, seed), qvel0, steps, None, run.ctrl)
    with actuated_scene(result, qpos0, qvel0, contacts=True):
        sp = sapien_ctrl_rollout(result, model, qpos0, qvel0, run.ctrl)
    diverged = first_divergence("settle", sp.qpos, sp.qvel, run.qvel, SpeedBound.from_tolerances(tolerances), dt)
    poses = compare_settled(result, model, run.body_pose, other.body_pose, sp)
    spread = poses.spread
    judged = trajectory(ref, run, sp, seed, tolerances, "actuated_contact.rollout_qpos")
    metrics = [
        metric("final_pose_band", poses.band, tolerances["actuated_contact.final_pose_band"], "m"),
        metric("rest_height", poses.rest, tolerances["actuated_contact.rest_height"], "m"),
        judged.metric,
    ]
    band = tolerances["actuated_contact.final_pose_band"]
    status, why = settled_verdict(metrics, spread, band, tolerances, diverged)
    notes = removal + _ctrl_notes(scale, left, steps, smooth=False) + why + judged.notes + untouched(run)
    time = np.arange(steps + 1) * dt
    return TierReport(
        "actuated_contact",
        status,
        metrics,
        notes,
        divergence=diverged,
        settings={
            **matched,
            "steps": steps,
            "start": start,
            "ctrl_scale": scale,
            "saturated_steps": left["saturated"],
            "limit_steps": left["at_limit"],
            "mujoco_self_spread": float(spread.max(initial=0.0)),
            "chaos": judged.gate.to_dict(),
        },
        series={"final_pose_band_per_step": poses.series},  # the largest body distance each step
        traces=[settle_trace(result, ref, run, sp, "actuated_contact")],
        actuators=ActuatorTrace(
            [a.name for a in result.actuators],
            time[:-1],
            commands.clip_ctrl(ref, run.ctrl),
            run.actuator_force,
            sp.force,
        ),
    )
