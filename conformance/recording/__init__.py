"""One Rerun recording per model, written headless with batched columns.

Layout (entity paths):
  mujoco/body/<body>                      per-step world transform of every MuJoCo body with a primitive
  mujoco/body/<body>/geom/<geom>          MuJoCo's primitive geoms and fitted planes (static, in the body frame)
  mujoco/mesh/<mesh>                      each distinct mesh once, with per-step world poses of the geoms using it
  sapien/link/<art>/<link>                per-step world transform of every SAPIEN link with a shape
  sapien/link/<art>/<link>/shape/<k>      the collision shapes PhysX holds, read back from the components (outlines)
  sapien/static/<actor>/shape/<k>         static actors' shapes (world frame)
  deviation                               per step, MuJoCo body -> SAPIEN body, magnified (geometry in scene.py)
  joints/<group>/{position,difference}    the shown rollout's joint series, one batch per joint group
  commands/<group>                        its generalized command, when it has one
  actuators/<tier>/<group>/{ctrl,force}   the actuated tiers' ctrl (as MuJoCo clamps it) and both sides' actuator
                                          force per step (report.ActuatorTrace says how the SAPIEN force is derived)
  tiers/<tier>/every_<k>_steps            each tier's error series over its tolerance, one batch per sampling
  tiers/tolerance                         the line at 1
  tier_series/<tier>/every_<k>_steps      series without a tolerance, as measured
  verdict                                 markdown: outcome and expectation per tier, seed, settings, versions

The 3D view plays the rollout of the tier that failed (the contact rollout when contact failed), else the PD
rollout (`test_rerun_recording.py::test_the_failing_contact_rollout_plays_with_the_floor`). Each run gets its own
recording id, and the model is in the application id and the recording name, so two runs never merge
(`test_rerun_recording.py::test_each_run_is_its_own_recording_named_after_the_model`).
"""

from __future__ import annotations

import re
import uuid
from pathlib import Path

import rerun as rr

from ..report import TierReport, Trace
from . import geometry, scene, series
from .blueprint import Layout, blueprint
from .geometry import MUJOCO_COLOR, SAPIEN_COLOR
from .paths import body_path, link_path, part
from .poses import Motion, xyzw
from .series import joint_groups
from .verdict import verdict_markdown

__all__ = [
    "MUJOCO_COLOR",
    "SAPIEN_COLOR",
    "body_path",
    "joint_groups",
    "link_path",
    "part",
    "recorded_trace",
    "verdict_markdown",
    "write_recording",
    "xyzw",
]

PREFERRED = ("pd", "torque", "zero", "actuated", "contact", "actuated_contact")  # when no rollout failed
FAILED = ("fail", "diverged")


def recorded_trace(reports: dict[str, TierReport]) -> Trace | None:
    """The rollout the 3D view plays: the first failing tier's (in run order), preferring a rollout whose own
    metric failed; else the first of PREFERRED."""
    for report in reports.values():
        if report.status in FAILED and report.traces:
            failed = {m.name for m in report.metrics if not m.passed}
            return next((t for t in report.traces if f"rollout_{t.name}_qpos" in failed), report.traces[0])
    traces = {t.name: t for r in reports.values() for t in r.traces}
    return next((traces[n] for n in PREFERRED if n in traces), None)


def application_id(model: str) -> str:
    """The model's own application id: the viewer keeps a layout per application, and models' layouts differ."""
    return "mjcf_sapien_conformance_" + re.sub(r"[^A-Za-z0-9_-]", "_", model)


def _tier_of(reports: dict[str, TierReport], trace: Trace) -> str:
    return next(tier for tier, r in reports.items() if any(t is trace for t in r.traces))


def write_recording(
    path: str | Path, session, reports: dict[str, TierReport], meta: dict, visual: bool = False
) -> Path:
    """Write `<model>.rrd`: geometry, the shown rollout, plots and the verdict text. `visual` also draws MuJoCo's
    visual-only geoms."""
    path = Path(path)
    model, result = session.model, session.result
    name = str(meta.get("model") or path.stem)
    rec = rr.RecordingStream(application_id(name), recording_id=str(uuid.uuid4()))
    trace = recorded_trace(reports)
    motion = Motion.of(trace) if trace is not None else Motion.still(model, result)
    box = geometry.bounding_box(model, motion)
    scale = scene.magnification(motion, box)
    shown = f"the {trace.name} rollout of {_tier_of(reports, trace)}" if trace is not None else "the start state"
    shown += f", contacts {'on' if motion.contact else 'off'}"
    if trace is not None:
        shown += f"; red arrows: SAPIEN's bodies off MuJoCo's x{scale}"
    span = float(motion.time[-1]) if motion.time is not None else None
    layout = Layout(
        f"MuJoCo (grey), SAPIEN (orange lines): {shown}", eye=scene.eye(geometry.start_box(model, motion)), span=span
    )
    tmp = path.with_name(f".{path.name}.partial")  # the runner removes it if the worker dies
    rec.save(tmp)
    rec.send_recording_name(f"{name} (seed {meta.get('seed')}, {path.parent.name})")
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    bodies = geometry.log_mujoco(rec, model, motion, box, visual)
    links = geometry.log_sapien(rec, result, motion, box)
    scene.log_frames(rec, model, result, motion, bodies, links)
    scene.log_deviation(rec, motion, scale)
    if trace is not None:
        layout.groups, layout.positioned, layout.commanded = series.log_joints(rec, model, trace)
    layout.actuated = series.log_actuators(rec, model, reports)
    every = int(reports["dynamics"].settings.get("one_step_every", 1)) if "dynamics" in reports else 1
    layout.raw_series = series.log_tiers(rec, reports, float(model.opt.timestep), every)
    rec.log(
        "verdict",
        rr.TextDocument(verdict_markdown(reports, {**meta, "shown": shown}), media_type=rr.MediaType.MARKDOWN),
        static=True,
    )
    rec.send_blueprint(blueprint(layout), make_active=True, make_default=True)
    rec.flush()
    rec.disconnect()
    tmp.replace(path)
    return path
