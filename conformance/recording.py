"""One Rerun recording per model, written headless with batched columns.

Layout (entity paths):
  mujoco/body/<body>                      per-step world transform of every MuJoCo body
  mujoco/body/<body>/geom/<geom>          MuJoCo's collision/visual geoms (static, in the body frame)
  sapien/link/<art>/<link>                per-step world transform of every SAPIEN link
  sapien/link/<art>/<link>/shape/<k>      the collision shapes PhysX holds, read back from the components
  sapien/static/<actor>/shape/<k>         static actors' shapes (world frame)
  joints/<joint>/{mujoco_q,sapien_q,difference,command}   time series of the recorded rollout
  tiers/<tier>/<series>                   each tier's error series
  actuators/<tier>/<actuator>/{ctrl,mujoco_force,sapien_force}   the actuated tiers' ctrl (as MuJoCo clamps it)
                                          and actuator-space force per step (report.ActuatorTrace says how the
                                          SAPIEN force is derived)
  verdict                                 markdown: verdict table, seed, settings, versions
Timelines: `step` (sequence) and `sim_time` (seconds); kinematics series use `configuration`.
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
import sapien

from . import sapien_side
from .report import TierReport, Trace

MUJOCO_COLOR = [150, 170, 200, 255]
SAPIEN_COLOR = [255, 140, 0, 110]  # translucent orange: SAPIEN is seen through, MuJoCo underneath
RECORDED_TRACE = ("pd", "torque", "zero")  # the first available rollout drives the 3D view
_Z_TO_X = np.array([0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])  # xyzw: +90 deg about y maps +Z to +X
_PLANE_HALF = 5.0


def part(name: str) -> str:
    return rr.escape_entity_path_part(name)


def body_path(model: mujoco.MjModel, b: int) -> str:
    return f"mujoco/body/{part(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f'body{b}')}"


def link_path(a: int, link) -> str:
    return f"sapien/link/{a}/{part(link.name)}"


def joint_path(model: mujoco.MjModel, j: int) -> str:
    return f"joints/{part(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint{j}')}"


def xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(q_wxyz, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def _mujoco_geom(model: mujoco.MjModel, g: int):
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    G = mujoco.mjtGeom
    color = [MUJOCO_COLOR]
    if kind == G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size[:3]], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size[:3]], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_CAPSULE:
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]],
                             colors=color)
    if kind == G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_PLANE:
        half = [size[0] or _PLANE_HALF, size[1] or _PLANE_HALF, 1e-3]
        return rr.Boxes3D(half_sizes=[half], colors=color, fill_mode="solid")
    if kind == G.mjGEOM_MESH:
        m = model.geom_dataid[g]
        verts = model.mesh_vert[model.mesh_vertadr[m]:model.mesh_vertadr[m] + model.mesh_vertnum[m]]
        faces = model.mesh_face[model.mesh_faceadr[m]:model.mesh_faceadr[m] + model.mesh_facenum[m]]
        return rr.Mesh3D(vertex_positions=verts, triangle_indices=faces, albedo_factor=MUJOCO_COLOR)
    return None  # height fields and SDFs are not drawn


def _sapien_shape(shape):
    P = sapien.physx
    color = [SAPIEN_COLOR]
    if isinstance(shape, P.PhysxCollisionShapeSphere):
        return rr.Ellipsoids3D(half_sizes=[[shape.radius] * 3], colors=color, fill_mode="solid")
    if isinstance(shape, P.PhysxCollisionShapeBox):
        return rr.Boxes3D(half_sizes=[shape.half_size], colors=color, fill_mode="solid")
    if isinstance(shape, P.PhysxCollisionShapeCapsule):  # SAPIEN's axis is +X
        return rr.Capsules3D(lengths=[2 * shape.half_length], radii=[shape.radius],
                             translations=[[-shape.half_length, 0, 0]], quaternions=[_Z_TO_X], colors=color)
    if isinstance(shape, P.PhysxCollisionShapeCylinder):
        return rr.Cylinders3D(lengths=[2 * shape.half_length], radii=[shape.radius], quaternions=[_Z_TO_X],
                              colors=color, fill_mode="solid")
    if isinstance(shape, P.PhysxCollisionShapePlane):
        return rr.Boxes3D(half_sizes=[[1e-3, _PLANE_HALF, _PLANE_HALF]], colors=color, fill_mode="solid")
    if isinstance(shape, (P.PhysxCollisionShapeConvexMesh, P.PhysxCollisionShapeTriangleMesh)):
        verts = np.asarray(shape.get_vertices(), dtype=float) * np.asarray(shape.get_scale(), dtype=float)
        return rr.Mesh3D(vertex_positions=verts, triangle_indices=np.asarray(shape.get_triangles()),
                         albedo_factor=SAPIEN_COLOR)
    return None


def _static_pose(rec: rr.RecordingStream, path: str, p, q_wxyz) -> None:
    rec.log(path, rr.Transform3D(translation=np.asarray(p, dtype=float), quaternion=xyzw(q_wxyz)), static=True)


def log_geometry(rec: rr.RecordingStream, model: mujoco.MjModel, result) -> None:
    """Both sides' static geometry: MuJoCo geoms in body frames, SAPIEN shapes in link/actor frames."""
    for g in range(model.ngeom):
        shape = _mujoco_geom(model, g)
        if shape is None:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        path = f"{body_path(model, int(model.geom_bodyid[g]))}/geom/{part(name)}"
        _static_pose(rec, path, model.geom_pos[g], model.geom_quat[g])
        rec.log(path, shape, static=True)
    for a, link in sapien_side.links(result):
        for k, shape in enumerate(link.collision_shapes):
            drawn = _sapien_shape(shape)
            if drawn is not None:
                path = f"{link_path(a, link)}/shape/{k}"
                _static_pose(rec, path, shape.local_pose.p, shape.local_pose.q)
                rec.log(path, drawn, static=True)
    for i, actor in enumerate(result.actors):
        component = sapien_side.rigid_component(actor)
        for k, shape in enumerate(component.collision_shapes):
            drawn = _sapien_shape(shape)
            if drawn is not None:
                pose = sapien_side.shape_world_pose(component, shape)
                path = f"sapien/static/{part(actor.name or str(i))}/shape/{k}"
                _static_pose(rec, path, pose.p, pose.q)
                rec.log(path, drawn, static=True)


def _times(trace_time: np.ndarray) -> list:
    steps = np.arange(trace_time.size)
    return [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("sim_time", duration=trace_time)]


def log_trace(rec: rr.RecordingStream, model: mujoco.MjModel, result, trace: Trace) -> None:
    """Per-step transforms of every body and link, and per-joint q, difference and command series."""
    times = _times(trace.time)
    for b in range(1, model.nbody):
        pose = trace.mujoco_body_pose[:, b]
        rec.send_columns(body_path(model, b), indexes=times,
                         columns=rr.Transform3D.columns(translation=pose[:, :3], quaternion=xyzw(pose[:, 3:])))
    for row, (a, link) in enumerate(sapien_side.links(result)):
        pose = trace.sapien_link_pose[:, row]
        rec.send_columns(link_path(a, link), indexes=times,
                         columns=rr.Transform3D.columns(translation=pose[:, :3], quaternion=xyzw(pose[:, 3:])))
    for j in range(model.njnt):
        qa, da = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        nq = {0: 7, 1: 4}.get(int(model.jnt_type[j]), 1)
        nv = {0: 6, 1: 3}.get(int(model.jnt_type[j]), 1)
        base = joint_path(model, j)
        for name, values in (("mujoco_q", trace.mujoco_qpos[:, qa:qa + nq]),
                             ("sapien_q", trace.sapien_qpos[:, qa:qa + nq]),
                             ("difference", trace.qpos_error[:, da:da + nv]),
                             ("command", trace.command[:, da:da + nv])):
            rec.send_columns(f"{base}/{name}", indexes=times, columns=rr.Scalars.columns(scalars=values))


def log_tier_series(rec: rr.RecordingStream, reports: dict[str, TierReport], dt: float, every: int) -> None:
    for tier, report in reports.items():
        for name, values in report.series.items():
            values = np.asarray(values, dtype=float)
            if tier == "kinematics":
                indexes = [rr.TimeColumn("configuration", sequence=np.arange(values.size))]
            else:
                stride = int(report.settings.get("one_step_every", every)) if name.startswith("one_step") else 1
                steps = np.arange(values.size) * stride
                indexes = [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("sim_time", duration=steps * dt)]
            rec.send_columns(f"tiers/{tier}/{part(name)}", indexes=indexes, columns=rr.Scalars.columns(scalars=values))


def log_actuators(rec: rr.RecordingStream, reports: dict[str, TierReport]) -> None:
    """Per actuator of each actuated tier: the ctrl and both sides' actuator force, one scalar per step."""
    for tier, report in reports.items():
        trace = report.actuators
        if trace is None:
            continue
        times = _times(trace.time)
        for a, name in enumerate(trace.names):
            base = f"actuators/{part(tier)}/{part(name or f'actuator{a}')}"
            for series, values in (("ctrl", trace.ctrl), ("mujoco_force", trace.mujoco_force),
                                   ("sapien_force", trace.sapien_force)):
                rec.send_columns(f"{base}/{series}", indexes=times,
                                 columns=rr.Scalars.columns(scalars=np.asarray(values[:, a], dtype=float)))


def verdict_markdown(reports: dict[str, TierReport], meta: dict) -> str:
    lines = [f"# {meta.get('model', '')}", "", "| tier | status | metric | max | rms | tolerance | margin |",
             "|---|---|---|---|---|---|---|"]
    for tier, report in reports.items():
        if report.divergence is not None:
            lines.append(f"| {tier} | diverged | first bad step: {report.divergence.text()} | | | | |")
        if not report.metrics:
            lines.append(f"| {tier} | {report.status} | | | | | |")
        for m in report.metrics:
            lines.append(f"| {tier} | {report.status} | {m.name} | {m.max:.3g} | {m.rms:.3g} | "
                         f"{m.tolerance:.3g} {m.unit} | {m.margin:.3g} |")
    isolation = {tier: runs for tier, runs in meta.get("isolation", {}).items() if runs}
    if isolation:
        from .summary import isolation_text

        lines += ["", "## Isolation (the failing tier rerun with known gaps removed on both sides)", ""]
        lines += [f"- {tier}: " + isolation_text(runs) for tier, runs in isolation.items()]
    lines += ["", f"seed: {meta.get('seed')}", "", "versions: " + ", ".join(
        f"{k} {v}" for k, v in meta.get("versions", {}).items()), "", "## Notes"]
    for tier, report in reports.items():
        lines += [f"- {tier}: {n}" for n in report.notes[:10]]
    lines += ["", "## Settings", "```json", json.dumps(meta.get("settings", {}), indent=1, default=str), "```"]
    return "\n".join(lines)


def blueprint() -> rrb.Blueprint:
    """Both models in one 3D view (SAPIEN translucent orange), time series below, verdict text beside."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name="MuJoCo (grey) and SAPIEN (orange)", origin="/",
                                  contents=["+ /mujoco/**", "+ /sapien/**"]),
                rrb.TextDocumentView(name="verdict", origin="/verdict"),
                column_shares=[3, 2],
            ),
            rrb.Horizontal(
                rrb.TimeSeriesView(name="joints", origin="/joints"),
                rrb.TimeSeriesView(name="actuators (ctrl, force)", origin="/actuators"),
                rrb.TimeSeriesView(name="tier errors", origin="/tiers"),
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def recorded_trace(reports: dict[str, TierReport]) -> Trace | None:
    traces = {t.name: t for r in reports.values() for t in r.traces}
    return next((traces[n] for n in RECORDED_TRACE if n in traces), None)


def write_recording(path: str | Path, session, reports: dict[str, TierReport], meta: dict) -> Path:
    """Write `<model>.rrd`: geometry, the recorded rollout, tier series and the verdict text."""
    path = Path(path)
    model, result = session.model, session.result
    rec = rr.RecordingStream("mjcf_sapien_conformance", recording_id=f"{meta.get('model')}-{meta.get('seed')}")
    tmp = path.with_name(f".{path.name}.partial")  # the runner removes it if the worker dies
    rec.save(tmp, default_blueprint=blueprint())
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_geometry(rec, model, result)
    trace = recorded_trace(reports)
    if trace is not None:
        log_trace(rec, model, result, trace)
    every = int(reports["dynamics"].settings.get("one_step_every", 1)) if "dynamics" in reports else 1
    log_tier_series(rec, reports, float(model.opt.timestep), every)
    log_actuators(rec, reports)
    rec.log("verdict", rr.TextDocument(verdict_markdown(reports, meta), media_type=rr.MediaType.MARKDOWN),
            static=True)
    rec.flush()
    rec.disconnect()
    tmp.replace(path)
    return path
