"""The .rrd files are read back and checked against the simulation they were written from."""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pyarrow as pa
import pytest
import rerun.chunk as rc

from conformance import recording, sapien_side, tolerances
from conformance.session import open_session
from conformance.tiers import TIERS

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "corpus" / "fixtures" / "pendulum.xml"


def read_rrd(path: Path) -> dict[str, dict[str, list]]:
    """entity path -> column name -> concatenated values over every chunk (static rows included)."""
    out: dict[str, dict[str, list]] = {}
    for chunk in rc.RrdReader(str(path)).stream():
        batch: pa.RecordBatch = chunk.to_record_batch()
        columns = out.setdefault(chunk.entity_path, {})
        for name in batch.schema.names:
            columns.setdefault(name, []).extend(batch.column(name).to_pylist())
    return out


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = open_session(str(FIXTURE))
    tol = tolerances.load()
    reports = {name: tier(session.result, session.model, 7, tol) for name, tier in TIERS.items()}
    path = tmp_path_factory.mktemp("rrd") / "pendulum.rrd"
    recording.write_recording(path, session, reports, {"model": "pendulum", "seed": 7,
                                                       "versions": {"mujoco": mujoco.__version__}})
    return session, reports, read_rrd(path), path


def test_every_body_and_link_has_a_transform_per_step(recorded):
    session, reports, rrd, _ = recorded
    trace = recording.recorded_trace(reports)
    assert trace is not None and trace.name == "pd"
    steps = trace.time.size
    model = session.model
    for b in range(1, model.nbody):
        entity = "/" + recording.body_path(model, b)
        rows = rrd[entity]
        assert len(rows["step"]) == steps
        np.testing.assert_array_equal(rows["step"], np.arange(steps))
        translation = np.array([r[0] for r in rows["Transform3D:translation"]])
        np.testing.assert_allclose(translation, trace.mujoco_body_pose[:, b, :3], atol=1e-6)
    for row, (a, link) in enumerate(sapien_side.links(session.result)):
        rows = rrd["/" + recording.link_path(a, link)]
        assert len(rows["sim_time"]) == steps
        quaternion = np.array([r[0] for r in rows["Transform3D:quaternion"]])
        np.testing.assert_allclose(quaternion, recording.xyzw(trace.sapien_link_pose[:, row, 3:]), atol=1e-6)


def test_sim_time_is_steps_times_timestep(recorded):
    session, _, rrd, _ = recorded
    rows = rrd["/" + recording.body_path(session.model, 1)]
    seconds = np.array([t.total_seconds() for t in rows["sim_time"]])
    np.testing.assert_allclose(seconds, np.arange(len(seconds)) * session.model.opt.timestep, atol=1e-9)


def test_joint_series_match_both_simulations(recorded):
    session, reports, rrd, _ = recorded
    trace = recording.recorded_trace(reports)
    model = session.model
    for j in range(model.njnt):
        base = "/" + recording.joint_path(model, j)
        adr, dof = model.jnt_qposadr[j], model.jnt_dofadr[j]
        mj = np.array([v[0] for v in rrd[f"{base}/mujoco_q"]["Scalars:scalars"]])
        sp = np.array([v[0] for v in rrd[f"{base}/sapien_q"]["Scalars:scalars"]])
        diff = np.array([v[0] for v in rrd[f"{base}/difference"]["Scalars:scalars"]])
        cmd = np.array([v[0] for v in rrd[f"{base}/command"]["Scalars:scalars"]])
        np.testing.assert_array_equal(mj, trace.mujoco_qpos[:, adr])
        np.testing.assert_array_equal(sp, trace.sapien_qpos[:, adr])
        np.testing.assert_allclose(diff, sp - mj, atol=1e-12)
        np.testing.assert_array_equal(cmd, trace.command[:, dof])
        assert np.abs(cmd).max() > 0, "the PD rollout commands every hinge"


def test_tier_error_series_are_recorded(recorded):
    _, reports, rrd, _ = recorded
    for tier, report in reports.items():
        for name, values in report.series.items():
            rows = rrd[f"/tiers/{tier}/{name}"]["Scalars:scalars"]
            np.testing.assert_allclose([v[0] for v in rows], values)
    assert "/tiers/dynamics/rollout_pd_qpos" in rrd


def test_static_geometry_of_both_sides(recorded):
    session, _, rrd, _ = recorded
    model = session.model
    capsule = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "rod")
    entity = f"/{recording.body_path(model, int(model.geom_bodyid[capsule]))}/geom/rod"
    assert rrd[entity]["Capsules3D:radii"][-1] == pytest.approx([model.geom_size[capsule][0]], rel=1e-6)
    # SAPIEN's shapes come from the components PhysX simulates
    shapes = [(a, link, k, s) for a, link in sapien_side.links(session.result)
              for k, s in enumerate(link.collision_shapes)]
    assert shapes
    for a, link, k, shape in shapes:
        cols = rrd[f"/{recording.link_path(a, link)}/shape/{k}"]
        local = np.array(cols["Transform3D:translation"][-1][0])
        np.testing.assert_allclose(local, shape.local_pose.p, atol=1e-7)
        if hasattr(shape, "half_size"):
            np.testing.assert_allclose(cols["Boxes3D:half_sizes"][-1][0], shape.half_size, rtol=1e-6)
        if hasattr(shape, "half_length"):
            assert cols["Capsules3D:lengths"][-1][0] == pytest.approx(2 * shape.half_length, rel=1e-6)
    assert any(p.startswith("/sapien/static/") for p in rrd), "world geoms live in a static actor"


def test_verdict_text_names_every_tier_seed_and_versions(recorded):
    _, reports, rrd, _ = recorded
    text = rrd["/verdict"]["TextDocument:text"][-1][0]
    for tier, report in reports.items():
        assert f"| {tier} | {report.status} |" in text
    assert "seed: 7" in text and f"mujoco {mujoco.__version__}" in text


def test_default_blueprint_shows_both_models_series_and_verdict(recorded):
    *_, path = recorded
    reader = rc.RrdReader(str(path))
    (blueprint,) = list(reader.blueprints())
    views = {}
    for chunk in reader.stream(store=blueprint):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in batch.schema.names:
            kind = batch.column("ViewBlueprint:class_identifier").to_pylist()[-1][0]
            origin = batch.column("ViewBlueprint:space_origin").to_pylist()[-1][0]
            views.setdefault(kind, set()).add(origin)
    assert views == {"3D": {"/"}, "TimeSeries": {"/joints", "/actuators", "/tiers"}, "TextDocument": {"/verdict"}}
