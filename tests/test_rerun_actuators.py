"""The actuated tiers' series in the .rrd, read back: ctrl and both sides' actuator force per actuator and step,
and the tier's error series; MuJoCo's forces are checked against MuJoCo itself, not against the harness."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from test_rerun_recording import line, read_rrd, tier_line
from test_tiers_actuated import ARM, _session

from conformance import recording, tolerances
from conformance.tiers import TIERS


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rrd")
    path = folder / "arm.xml"
    path.write_text(ARM)
    session = _session(path)
    tol = tolerances.load()
    reports = {name: tier(session.result, session.model, 3, tol) for name, tier in TIERS.items()}
    rrd = folder / "arm.rrd"
    recording.write_recording(
        rrd, session, reports, {"model": "arm", "seed": 3, "versions": {"mujoco": mujoco.__version__}}
    )
    return session, reports, read_rrd(rrd)


def _plot_of(rrd, tier: str, quantity: str, name: str) -> str:
    """The one plot of `quantity` (ctrl, force) in `tier` that has a line called `name`."""
    (entity,) = [
        e
        for e, cols in rrd.items()
        if e.startswith(f"/actuators/{tier}/") and e.endswith(f"/{quantity}") and name in cols["SeriesLines:names"][-1]
    ]
    return entity


def _ctrl(rrd, tier: str, name: str) -> np.ndarray:
    return line(rrd, _plot_of(rrd, tier, "ctrl", name), name)


def _force(rrd, tier: str, side: str, name: str) -> np.ndarray:
    return line(rrd, _plot_of(rrd, tier, "force", f"{side} {name}"), f"{side} {name}")


@pytest.mark.parametrize("tier", ["actuated", "actuated_contact"])
def test_ctrl_and_forces_per_actuator_are_recorded(recorded, tier):
    _, reports, rrd = recorded
    trace = reports[tier].actuators
    assert trace.names == ["servo", "torque", "coupled"]
    for a, name in enumerate(trace.names):
        np.testing.assert_array_equal(_ctrl(rrd, tier, name), trace.ctrl[:, a])
        np.testing.assert_array_equal(_force(rrd, tier, "MuJoCo", name), trace.mujoco_force[:, a])
        np.testing.assert_array_equal(_force(rrd, tier, "SAPIEN", name), trace.sapien_force[:, a])
        seconds = [t.total_seconds() for t in rrd[_plot_of(rrd, tier, "ctrl", name)]["sim_time"]]
        np.testing.assert_allclose(seconds, trace.time, atol=1e-9)
        assert np.ptp(trace.ctrl[:, a]) > 0, "every actuator's ctrl moves (the hold, then a step)"


def test_recorded_force_is_what_mujoco_computes_for_the_recorded_ctrl(recorded):
    """Replay the recorded ctrl on a fresh MuJoCo (its own Euler, contact off, from qpos0 at rest)."""
    session, _, rrd = recorded
    names = ("servo", "torque", "coupled")
    ctrl = np.stack([_ctrl(rrd, "actuated", n) for n in names], axis=1)
    force = np.stack([_force(rrd, "actuated", "MuJoCo", n) for n in names], axis=1)
    model = mujoco.MjModel.from_xml_path(session.path)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    replayed = np.zeros_like(force)
    for step in range(ctrl.shape[0]):
        data.ctrl[:] = ctrl[step]
        mujoco.mj_step(model, data)
        replayed[step] = data.actuator_force
    np.testing.assert_allclose(force, replayed, rtol=0, atol=1e-12)
    # and SAPIEN's force law on SAPIEN's state follows it (the states agree to 1e-6 rad on this arm)
    sapien = np.stack([_force(rrd, "actuated", "SAPIEN", n) for n in names], axis=1)
    np.testing.assert_allclose(sapien, force, atol=1e-4)


def test_actuated_error_series_are_recorded(recorded):
    session, reports, rrd = recorded
    report = reports["actuated"]
    tolerance = {m.name: m.tolerance for m in report.metrics}
    for name in ("rollout_qpos", "one_step_qvel"):
        np.testing.assert_allclose(tier_line(rrd, "actuated", name)[1], report.series[name] / tolerance[name])
    entity, _ = tier_line(rrd, "actuated", "one_step_qvel")
    seconds = np.array([t.total_seconds() for t in rrd[entity]["sim_time"]])
    every, dt = report.settings["one_step_every"], session.model.opt.timestep
    np.testing.assert_allclose(seconds / dt, np.arange(len(seconds)) * every, atol=1e-6)


def test_actuators_are_plotted_with_their_joints_limb(recorded):
    """The servo (shoulder) and the motor (elbow) drive one arm: one plot; the tendon motor is plotted apart."""
    *_, rrd = recorded
    for tier in ("actuated", "actuated_contact"):
        assert _plot_of(rrd, tier, "ctrl", "servo") == _plot_of(rrd, tier, "ctrl", "torque")
        assert _plot_of(rrd, tier, "ctrl", "coupled") != _plot_of(rrd, tier, "ctrl", "servo")
        assert _plot_of(rrd, tier, "force", "MuJoCo servo") == _plot_of(rrd, tier, "force", "SAPIEN torque")
