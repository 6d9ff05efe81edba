"""Properties of a loader on one MJCF document, with MuJoCo as the oracle.

- MuJoCo compiles it: the loader loads it; its actuators and joint drives hold the gains MuJoCo compiled
  (`actuators.py`); and the harness's own tiers pass (structure, kinematics, inertia, collision, and short
  contact-free `actuated` and `dynamics` runs). Failures confined to elements the loader itself lists in
  `result.unsupported` / `result.approximations`, or explained by an open bug on record (`known_bugs.py`), are
  excused; every excuse and skip is counted in the run's `Tally`.
- MuJoCo rejects it: the loader raises `MJCFError` carrying MuJoCo's message (`MissingAssetError` for a missing
  file), never another exception, and never a model.
"""

from __future__ import annotations

import atexit
import itertools
import os
import shutil
import tempfile
import warnings
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import mujoco
import numpy as np

from ..data_pool import borrowed
from ..report import TierReport
from ..session import quiet_load
from ..tiers import TIERS
from ..tolerances import Tolerances
from ..tolerances import load as load_tolerances
from .actuators import check_actuators
from .document import Document, RawDocument, write
from .known_bugs import known_bug
from .tally import Tally

STATIC_TIERS = ("structure", "kinematics", "inertia", "collision")
# A short contact-free run is enough to see joint damping/armature/inertia mistakes in the one-step error.
DYNAMICS_SETTINGS = {
    "dynamics": {"horizon_s": 0.02, "max_steps": 20, "one_step_every": 2},
    "actuated": {"horizon_s": 0.02, "max_steps": 20, "one_step_every": 2},
}
# Contact-free rollouts, with MuJoCo as the reference: passive (generalized forces) and under the same ctrl.
DYNAMIC_TIERS = ("actuated", "dynamics")
# Loader notes about joints change joint dynamics (springs implicit, ball joints as Euler angles): the dynamic
# tiers are skipped (and counted) on documents that carry one. The note on joint limits is not: it is about
# contacts, and these runs are contact-free, where MuJoCo's own limit rows are exact.
DYNAMICS_NOTE_KINDS = ("joint",)
# steps MuJoCo runs with its actuators on (zero ctrl) before a document's dynamic tiers are judged: an explicit
# kv (Euler) too strong for a light body diverges over tens of steps and MuJoCo flags it only at 1e10 (a fuzz find
# blew up at step 59 while 20 steps are judged)
ACTUATED_STABILITY_STEPS = 500


# PhysX holds poses in float32: an absolute position tolerance measured on metre-sized models must grow with
# the distances a generated model spans (slide ranges of 90 m in degree-unit documents, row 19). 2e-6 of the
# extent is about 16 float32 ulps: a fuzz find put a body at the end of a six-body rotated chain with a 136 m slide
# 1.1e-6 of its extent off (corpus/regressions/deep_chain_long_slide_float32.xml; 1e-6 before). The harness's own
# (larger) tolerance stays the floor.
FLOAT32_RELATIVE = 2e-6
EXTENT_SCALED = (
    "kinematics.position",
    "inertia.com",
    "collision.position",
    "structure.anchor",
    "dynamics.one_step_qpos_fixed",
    "dynamics.one_step_qpos_floating",
)  # slide q of 21 m: float32
# Likewise the one-step acceleration tolerances are absolute, measured where accelerations are tens of rad/s^2;
# a 0.1 kg sphere on two hinges accelerates at 1100 rad/s^2 and float32 alone gives 2e-6 of that. 1e-5 of the
# largest acceleration MuJoCo computes at the start (and that times dt for velocities) is the floor here.
ACCEL_RELATIVE = 1e-5
ACCEL_SCALED = ("dynamics.one_step_qacc_fixed", "dynamics.one_step_qacc_floating")
VELOCITY_SCALED = (
    "dynamics.one_step_qvel_fixed",
    "dynamics.one_step_qvel_floating",
    "actuated.one_step_qvel_fixed",
    "actuated.one_step_qvel_floating",
)
SINGULAR_TOLERANCE = 1e-9  # singular value of the stacked body Jacobians below which DoFs are redundant
_FREE_SPAN = 0.5  # m: how far the kinematics tier moves a free joint (conformance.sampling)
_SLIDE_SPAN = 0.2  # m: its span for an unlimited slide


@dataclass
class Outcome:
    """What the properties found on one document."""

    path: Path
    compiled: bool
    reports: dict[str, TierReport] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)
    excused: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    tier_errors: list[str] = field(default_factory=list)
    result: object = None  # loader.LoadResult when loaded

    @property
    def ok(self) -> bool:
        return not self.failures


@cache
def tolerances() -> Tolerances:
    """The harness's tolerances with the short dynamics settings, read once per process (3 ms a read): the tiers
    only read them, and `scaled_tolerances` makes its raised copies with `with_overrides`."""
    return load_tolerances().with_overrides(settings=DYNAMICS_SETTINGS, why="fragments: short dynamics")


def extent(model: mujoco.MjModel) -> float:
    """An upper bound of how far from the origin any body or geom gets in the kinematics tier's samples."""
    reach = 1.0 + float(
        np.abs(model.body_pos).sum() + np.abs(model.geom_pos).sum() + model.geom_rbound.max(initial=0.0)
    )
    for j in range(model.njnt):
        kind = int(model.jnt_type[j])
        if kind == int(mujoco.mjtJoint.mjJNT_FREE):
            reach += _FREE_SPAN + float(np.abs(model.qpos0[model.jnt_qposadr[j] :][:3]).sum())
        elif kind == int(mujoco.mjtJoint.mjJNT_SLIDE):
            span = np.abs(model.jnt_range[j]).max() if model.jnt_limited[j] else _SLIDE_SPAN
            reach += float(span) + abs(float(model.qpos0[model.jnt_qposadr[j]]))
    return reach


def start_acceleration(model: mujoco.MjModel) -> float:
    """Largest |qacc| MuJoCo computes at the tiers' initial state (contact-free reference), 0 without DoF."""
    if model.nv == 0:
        return 0.0
    from ..reference import initial_state, matched

    ref, _ = matched(model, contact=False)
    with borrowed(ref) as data:
        data.qpos[:], data.qvel[:], _ = initial_state(model)
        mujoco.mj_forward(ref, data)
        qacc = np.abs(data.qacc)
        return float(qacc.max()) if np.all(np.isfinite(qacc)) else 0.0


def scaled_tolerances(model: mujoco.MjModel, base: Tolerances | None = None) -> Tolerances:
    """`base` with absolute tolerances raised to what float32 allows on this model: positions to
    FLOAT32_RELATIVE times its extent, one-step accelerations (velocities) to ACCEL_RELATIVE times its largest
    start acceleration (times dt)."""
    base = base or tolerances()
    reach = extent(model)
    accel = ACCEL_RELATIVE * start_acceleration(model)
    floors = {
        **{key: FLOAT32_RELATIVE * reach for key in EXTENT_SCALED},
        **{key: accel for key in ACCEL_SCALED},
        **{key: accel * float(model.opt.timestep) for key in VELOCITY_SCALED},
    }
    raised = {key: value for key, value in floors.items() if key in base.entries and value > base[key]}
    why = f"float32 over a {reach:.3g} m extent and {accel / ACCEL_RELATIVE:.3g} rad/s^2 accelerations"
    return base.with_overrides(raised, why=why) if raised else base


def redundant_dofs(model: mujoco.MjModel, data: mujoco.MjData) -> bool:
    """Some combination of DoFs moves no body at qpos0 (the stacked body Jacobians lose rank)."""
    jacobians = []
    for body in range(1, model.nbody):
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, jacp, jacr, body)
        jacobians += [jacp, jacr]
    stacked = np.vstack(jacobians) if jacobians else np.zeros((0, model.nv))
    return bool(model.nv and np.linalg.matrix_rank(stacked, tol=SINGULAR_TOLERANCE) < model.nv)


# Explicit integration of a damper v' = -c v is stable while dt c stays inside the integrator's region on the
# negative real axis: 2 for Euler, 2.785 for RK4 (implicitfast and implicit treat actuator damping implicitly).
EXPLICIT_DAMPING_REGION = {int(mujoco.mjtIntegrator.mjINT_EULER): 2.0, int(mujoco.mjtIntegrator.mjINT_RK4): 2.785}


def joint_servos(model: mujoco.MjModel) -> list[tuple[int, int, float]]:
    """(actuator, DoF, gear^2) of each affine-bias actuator on a hinge or slide: the servos whose kp and kv MuJoCo
    may take explicitly."""
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    out = []
    for a in range(model.nu):
        joint = int(model.actuator_trnid[a, 0])
        if (
            int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
            and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
            and int(model.jnt_type[joint]) in scalar
        ):
            out.append((a, int(model.jnt_dofadr[joint]), float(model.actuator_gear[a, 0]) ** 2))
    return out


def inverse_inertia(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(M^-1)_dd per DoF at `data`'s state: 1 / each joint's effective inertia."""
    inverse = np.zeros((model.nv, model.nv))
    mujoco.mj_solveM(model, data, inverse, np.eye(model.nv))
    return np.diag(inverse)


def explicit_damping_unstable(model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
    """An actuator velocity gain MuJoCo integrates explicitly that is past its integrator's stability region on
    the joint it drives: dt kv gear^2 / M (M: the joint's effective inertia, 1 / (M^-1)_dd at the start). MuJoCo
    then grows the joint's speed by that factor minus one every step, and warns only at 1e10."""
    region = EXPLICIT_DAMPING_REGION.get(int(model.opt.integrator))
    servos = joint_servos(model) if region is not None else []
    if not servos:
        return None
    inverse = inverse_inertia(model, data)
    for a, dof, gear2 in servos:
        factor = model.opt.timestep * -float(model.actuator_biasprm[a, 2]) * gear2 * inverse[dof]
        if factor > region:
            return (
                f"MuJoCo itself is unstable with its actuators on (an explicit velocity gain past the "
                f"integrator's stability region: actuator {a}, dt kv/M = {factor:.3g} > {region:g})"
            )
    return None


# dt^2 kp / M beyond which an explicit spring's semi-implicit step grows (omega dt > 2; RK4: omega dt > 2.83)
EXPLICIT_STIFFNESS_REGION = {int(mujoco.mjtIntegrator.mjINT_RK4): 8.0}
EXPLICIT_STIFFNESS_DEFAULT = 4.0  # Euler, implicit and implicitfast: no integrator takes kp implicitly


def explicit_stiffness_unstable(model: mujoco.MjModel, data: mujoco.MjData, actuated: bool) -> str | None:
    """A joint's stiffness past the stability region of MuJoCo's step: dt^2 K / M, K the joint's spring plus
    (`actuated`) its position servos' kp gear^2, M its effective inertia (1 / (M^-1)_dd at the start). Every
    integrator takes stiffness explicitly; past the region MuJoCo rings the joint up a little more every step
    (tests/test_fragments_properties.py::test_an_explicit_servo_stiffness_past_the_step_s_region_is_no_reference)."""
    region = EXPLICIT_STIFFNESS_REGION.get(int(model.opt.integrator), EXPLICIT_STIFFNESS_DEFAULT)
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    stiffness = np.zeros(model.nv)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in scalar:
            stiffness[int(model.jnt_dofadr[j])] += float(model.jnt_stiffness[j])
    for a, dof, gear2 in joint_servos(model) if actuated else []:
        stiffness[dof] += max(-float(model.actuator_biasprm[a, 1]) * gear2, 0.0)
    if not stiffness.any():
        return None
    factor = model.opt.timestep**2 * stiffness * inverse_inertia(model, data)
    dof = int(np.argmax(factor))
    if factor[dof] > region:
        return (
            f"MuJoCo itself is unstable{' with its actuators on' if actuated else ' on the model'} (an explicit "
            f"stiffness past the integrator's stability region: dof {dof}, dt^2 K/M = {factor[dof]:.3g} > "
            f"{region:g})"
        )
    return None


def actuated_ill_posed(model: mujoco.MjModel) -> str | None:
    """Why MuJoCo's run with its actuators on is no reference though its passive run is (None when it is)."""
    from ..reference import matched

    ref, _ = matched(model, contact=False, actuation=True)
    with borrowed(ref) as data:
        mujoco.mj_forward(ref, data)
        return explicit_damping_unstable(ref, data) or explicit_stiffness_unstable(ref, data, actuated=True)


def mujoco_ill_posed(model: mujoco.MjModel, steps: int) -> str | None:
    """Why MuJoCo's own dynamics are no reference (None when they are): a singular joint-space inertia (two
    hinges on one axis: only their sum is determined), or a blow-up (bad qacc) within the horizon."""
    from ..reference import initial_state, matched

    ref, _ = matched(model, contact=False)
    with borrowed(ref) as data:
        mujoco.mj_forward(ref, data)
        if redundant_dofs(ref, data):  # two slides on one axis: MuJoCo need not warn
            return "redundant DoFs (two joints move a body the same way): no unique acceleration to compare"
        if (springy := explicit_stiffness_unstable(ref, data, actuated=False)) is not None:
            return springy.split(" (")[0]  # tallied with the blow-ups
        for _ in range(steps):
            mujoco.mj_step(ref, data)
        if data.warning[int(mujoco.mjtWarning.mjWARN_INERTIA)].number:
            return "MuJoCo's joint-space inertia is singular (mjWARN_INERTIA)"
        if data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number or not np.all(np.isfinite(data.qpos)):
            return "MuJoCo itself is unstable on the model (bad qacc)"
        if model.nu:  # explicit actuator gains (kv under Euler) can diverge slowly, past the short judged horizon
            ref, _ = matched(model, contact=False, actuation=True)
            # from where the tiers start (the model's own start), with a seed velocity: at rest with zero ctrl
            # a growing mode may never start
            if blows_up(ref, initial_state(model)[0], np.full(model.nv, 1e-3), max(steps, ACTUATED_STABILITY_STEPS)):
                return "MuJoCo itself is unstable on the model with its actuators on (bad qacc)"
        return None


def blows_up(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, steps: int) -> bool:
    """MuJoCo flags a bad qacc (or computes a non-finite one) within `steps` steps from (qpos, qvel), zero ctrl
    and no applied force: `reference.rollout(...).unstable` without recording the states it does not need."""
    with borrowed(model) as data:
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        bad = data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        for _ in range(steps):
            mujoco.mj_step(model, data)
            if bad.number or not np.all(np.isfinite(data.qacc)):
                return True
        return False


def compile_with_mujoco(path: Path) -> tuple[mujoco.MjModel | None, str | None]:
    try:
        return mujoco.MjModel.from_xml_path(str(path)), None
    except ValueError as error:
        return None, str(error)


def load(path: Path):
    """The loader on `path` as the harness runs it (`session.quiet_load`); MuJoCo's own compiler warnings on
    generated documents (near-singular inertia and the like) are silenced too."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return quiet_load(path)


def check_error_parity(path: Path, mujoco_error: str) -> list[str]:
    """MuJoCo rejected `path`: the loader must raise its typed error with MuJoCo's message."""
    from loader import MissingAssetError, MJCFError

    try:
        load(path)
    except MJCFError as error:
        failures = []
        if error.mujoco_message.strip() != mujoco_error.strip():
            failures.append(
                f"loader error message {error.mujoco_message!r} differs from MuJoCo's {mujoco_error.strip()!r}"
            )
        missing_file = "error opening file" in mujoco_error.lower()
        if missing_file and not isinstance(error, MissingAssetError):
            failures.append(
                f"MuJoCo could not open a file but the loader raised {type(error).__name__}, not MissingAssetError"
            )
        return failures
    except Exception as error:  # noqa: BLE001 - any other exception is exactly the bug to report
        return [
            (
                f"MuJoCo rejects the document ({mujoco_error.splitlines()[0]}) and the loader crashed with "
                f"{type(error).__name__}: {error}"
            )
        ]
    return [f"MuJoCo rejects the document ({mujoco_error.splitlines()[0]}) but the loader returned a model"]


def _noted_names(result) -> set[str]:
    """The elements the loader noted, but for joints noted only for their limit (mapped as MuJoCo's rows: a
    failure on such a joint is not excused by the note)."""
    return {entry.name for entry in [*result.unsupported, *result.approximations] if not _about_limits(entry)}


def _excusable(report: TierReport, noted: set[str]) -> bool:
    """A failing tier whose failing metrics are counts and whose every note names a noted element."""
    failing = [m for m in report.metrics if not m.passed]
    if not failing or any(m.name not in ("mismatches", "groups") for m in failing):
        return False
    problems = [note for note in report.notes if ":" in note]
    return bool(problems) and all(note.split(":", 1)[0] in noted for note in problems)


def check_tiers(
    result,
    model: mujoco.MjModel,
    tiers=STATIC_TIERS,
    dynamics: bool = True,
    seed: int = 0,
    tol: Tolerances | None = None,
    known_bugs: bool = True,
):
    """Run the harness's tiers on a load result: (reports, failures, excused, skipped, tier errors).

    A tier that raises is a harness problem: it is returned apart (callers count it, regressions fail on it).
    `known_bugs`: failures explained by an open bug on record (`known_bugs.py`) are excused and counted."""
    tol = scaled_tolerances(model, tol)
    reports, failures, excused, skipped, errors = {}, [], [], [], []
    noted = _noted_names(result)
    names = list(tiers)
    if dynamics:
        _add_dynamic_tiers(result, model, tol, names, skipped)
    for name in names:
        try:
            report = TIERS[name](result, model, seed, tol)
        except Exception as error:  # noqa: BLE001 - a harness error is reported, not mistaken for a loader bug
            errors.append(f"{name}: tier raised {type(error).__name__}: {error}")
            continue
        reports[name] = report
        if report.status == "skipped":
            skipped.append(f"{name}: {report.notes[0] if report.notes else 'skipped'}")
        elif report.status == "diverged":  # no note describes a blow-up; a known bug only where its finds diverge
            where = report.divergence.text() if report.divergence else "a metric is not finite"
            bug = known_bug(name, result, model, diverged=True) if known_bugs else None
            if bug is None:
                failures.append(f"{name} tier diverged: {where}")
            else:
                excused.append(f"{name}: known bug {bug} (diverged: {where})")
        elif report.status == "fail":
            _file_failure(name, report, result, model, noted, known_bugs, failures, excused)
    return reports, failures, excused, skipped, errors


def _add_dynamic_tiers(result, model: mujoco.MjModel, tol: Tolerances, names: list[str], skipped: list[str]) -> None:
    """Adds the dynamic tiers to `names`: none after loader notes on joints or where MuJoCo's own problem is
    ill-posed, and not `actuated` where explicit gains are unstable (each skip goes to `skipped`)."""
    joint_notes = [
        e
        for e in [*result.unsupported, *result.approximations]
        if e.kind in DYNAMICS_NOTE_KINDS and not _about_limits(e)
    ]
    if joint_notes:
        skipped.append(f"dynamics and actuated: loader notes on joints ({_reason(joint_notes[0])})")
        return
    if model.nv and (ill := mujoco_ill_posed(model, tol.horizon_steps("dynamics", model.opt.timestep))):
        skipped.append(f"dynamics and actuated: {ill}")
        return
    names += [tier for tier in DYNAMIC_TIERS if tier in TIERS]
    if "actuated" in names and (unstable := actuated_ill_posed(model)):
        names.remove("actuated")
        gain = unstable.split("an explicit ")[1].split(" past")[0]  # velocity gain or stiffness
        skipped.append(f"actuated: {unstable.split(' (')[0]} (explicit {gain})")  # tallied alike


def _file_failure(
    name: str,
    report: TierReport,
    result,
    model: mujoco.MjModel,
    noted: set[str],
    known_bugs: bool,
    failures: list[str],
    excused: list[str],
) -> None:
    """A failing tier report, filed as excused (by loader notes, a known bug, or one_step_qacc alone) or as a
    failure."""
    bug = known_bug(name, result, model) if known_bugs else None
    if _excusable(report, noted):
        excused.append(f"{name}: " + "; ".join(report.notes))
    elif bug is not None:
        excused.append(f"{name}: known bug {bug}")
    elif _qacc_only(report):
        excused.append(
            f"{name}: one_step_qacc only; one_step_qvel (the same velocity increment, "
            "not divided by dt) is within its tolerance"
        )
    else:
        failing = [f"{m.name} {m.max:.3g} > {m.tolerance:.3g} {m.unit}" for m in report.metrics if not m.passed]
        failures.append(f"{name} tier fails: {', '.join(failing)}; notes: {report.notes[:5]}")


def _qacc_only(report: TierReport) -> bool:
    """The dynamics tier fails on one_step_qacc alone. qacc is the one-step velocity increment / dt, which
    one_step_qvel also measures; at dt = 2 ms the qacc tolerance (2e-3) is 2.5x stricter than the qvel one
    (1e-5 / dt), and near-axial centres of mass on light bodies land in between (a fuzz finding: 0.15 % of a
    1 rad/s^2 acceleration, rollouts agreeing to 3e-7 rad)."""
    failing = {m.name for m in report.metrics if not m.passed}
    qvel = {m.name: m for m in report.metrics}.get("one_step_qvel")
    return failing == {"one_step_qacc"} and qvel is not None and qvel.passed


def _about_limits(entry) -> bool:
    """Notes on joint limits (solved with MuJoCo's contacts; ball cones): they do not skip the contact-free tiers."""
    return entry.kind == "joint limits" or (entry.kind == "joint" and "limit" in entry.reason)


def _reason(entry) -> str:
    """A note's reason without its numbers, so that tallies group alike notes."""
    return "".join(c if not c.isdigit() else "#" for c in entry.reason.split(":")[0]).replace("#.#", "#")


def check_path(
    path: Path,
    tiers=STATIC_TIERS,
    dynamics: bool = True,
    actuators: bool = True,
    strict: bool = False,
    tally: Tally | None = None,
) -> Outcome:
    """Every property on the document at `path` (meshes beside it). `strict` (regression replays): a tier that
    raises is a failure and open bugs on record are not excused; otherwise both are counted in `tally` (the
    run's; None: not counted)."""
    path = Path(path)
    tally = Tally() if tally is None else tally
    model, mujoco_error = compile_with_mujoco(path)
    if model is None:
        tally["rejected by MuJoCo"] += 1
        return Outcome(path, False, failures=check_error_parity(path, mujoco_error))
    tally["compiled by MuJoCo"] += 1
    from loader import MJCFError

    try:
        result = load(path)
    except MJCFError as error:
        return Outcome(path, True, failures=[f"MuJoCo compiles the document but the loader raised {error}"])
    outcome = Outcome(path, True, result=result)
    if actuators:
        checked, dofs = check_actuators(result, outcome)
        tally["actuators checked"] += checked
        tally["drive gains checked (dofs)"] += dofs
    result.disable_actuators()  # the tiers' reference runs with actuation disabled (conformance.reference)
    reports, failures, excused, skipped, errors = check_tiers(
        result, result.model, tiers, dynamics, known_bugs=not strict
    )
    outcome.tier_errors = errors
    if strict:
        outcome.failures += errors
    outcome.reports = reports
    outcome.failures += failures
    outcome.excused += excused
    outcome.skipped += skipped
    for name, report in reports.items():
        tally[f"tier {name} {report.status}"] += 1
    for entry in excused:
        tier, why = entry.split(": ", 1)
        listed = why.startswith(("known bug", "one_step_qacc only"))
        tally[f"excused {tier}: {why if listed else 'element the loader lists'}"] += 1
    for entry in outcome.skipped:
        tally[f"skipped {entry}"] += 1
    for entry in errors:
        tally[f"harness error {entry.split(':', 2)[0]}: {entry.split(':', 2)[1].strip()}"] += 1
    return outcome


_SCRATCH: dict[int, tuple[Path, itertools.count]] = {}


def _scratch() -> tuple[Path, str]:
    """This process's scratch folder, made once (making and removing a folder per document cost 2-3 ms on ext4),
    and a file stem no earlier document of the process used (MuJoCo caches assets by file name)."""
    pid = os.getpid()  # a forked process makes its own
    if pid not in _SCRATCH:
        folder = Path(tempfile.mkdtemp(prefix="fragments-"))
        atexit.register(shutil.rmtree, folder, True)
        _SCRATCH[pid] = folder, itertools.count()
    folder, numbers = _SCRATCH[pid]
    return folder, f"fragment{next(numbers)}"


def check_document(
    document: Document | RawDocument,
    tiers=STATIC_TIERS,
    dynamics: bool = True,
    actuators: bool = True,
    tally: Tally | None = None,
) -> Outcome:
    """Write `document` (meshes beside it) into the scratch folder under a new name, check it with `check_path`,
    and delete its files: no document sees another's."""
    folder, stem = _scratch()
    try:
        outcome = check_path(write(document, folder, stem), tiers, dynamics, actuators, tally=tally)
        outcome.result = None  # the scene outlives the files only as long as needed
        return outcome
    finally:
        for path in folder.glob(f"{stem}.*"):
            path.unlink()


def assert_conforms(
    document: Document | RawDocument,
    tiers=STATIC_TIERS,
    dynamics: bool = True,
    actuators: bool = True,
    property_name: str = "fragment",
    tally: Tally | None = None,
) -> Outcome:
    """`check_document`, raising AssertionError with the document on failure (and saving the shrunk
    counterexample into the regression corpus on hypothesis's final replay)."""
    outcome = check_document(document, tiers, dynamics, actuators, tally)
    if outcome.failures:
        from .regressions import save_if_final

        saved = save_if_final(document, property_name)
        xml = document.render()[0]
        where = f"\nsaved as {saved}" if saved else ""
        raise AssertionError("\n".join(outcome.failures) + f"{where}\n--- document ---\n{xml}")
    return outcome
