"""Passive forces: fixed-tendon springs and dampers, the spring/damper flags, fluid drag, gravity compensation."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import contact_free, no_ctrl, one_step, replay
from test_loader_actuators import SERVO_TOLERANCE

from loader import MJCFLoader

PASSIVE_TENDON = """<mujoco><option timestep="0.002" gravity="0 0 0" integrator="{integrator}"/>
  <worldbody><body name="base">
    <body name="a"><joint name="a" axis="0 0 1" damping="0.01"/>
      <geom type="box" size=".1 .02 .02" pos=".1 0 0" mass=".5"/></body>
    <body name="b" pos="0 .5 0"><joint name="b" axis="0 0 1"/>
      <geom type="box" size=".15 .02 .02" pos=".15 0 0" mass=".8"/></body>
    <body name="c" pos="0 1 0"><joint name="c" axis="0 0 1"/>
      <geom type="box" size=".1 .02 .02" pos=".1 0 0" mass=".3"/></body>
  </body></worldbody>
  <tendon><fixed name="t" stiffness="0.4" damping="0.05">
    <joint joint="a" coef="1"/><joint joint="b" coef="-0.5"/><joint joint="c" coef="0.5"/></fixed></tendon>
  <keyframe><key qpos="0.4 -0.3 0.2" qvel="1 0 -2"/></keyframe>
</mujoco>"""


TENDON_TOLERANCE = 1e-5  # rad over 1 s, measured 4.2e-7 (implicitfast), 4.0e-7 (Euler); the mutations 2.3e-3


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("integrator", ["implicitfast", "Euler"])
def test_a_passive_fixed_tendon_matches_mujoco(tmp_path, monkeypatch, integrator):
    """A tendon spring-damper over three hinges (coefficients 1, -0.5, 0.5): Euler takes the damper explicitly,
    implicitfast its whole D J^T J implicitly, of which the drives hold the diagonal (the rest explicit, noted); the
    loader follows the model's integrator. The mutation (the other treatment) must fail."""
    path = mjcf_file(tmp_path, PASSIVE_TENDON.format(integrator=integrator), "tendon.xml")

    def load():
        result, model = contact_free(path)
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER if integrator == "Euler" else model.opt.integrator
        return result, model

    result, model = load()
    assert len(result.controller.term("tendons").tendons) == 1
    assert any("J^T J" in str(note) for note in result.approximations) == (integrator != "Euler")
    errors = replay(result, model, no_ctrl, 1.0)
    assert errors.max() < TENDON_TOLERANCE, errors.max()
    import loader.model.options

    implicit = (int(mujoco.mjtIntegrator.mjINT_EULER),) if integrator == "Euler" else ()
    monkeypatch.setattr(loader.model.options, "IMPLICIT", implicit)  # the options snapshot reads the rule there
    other, model = load()
    assert replay(other, model, no_ctrl, 1.0).max() > 10 * TENDON_TOLERANCE


FLUID = """<mujoco><option timestep="0.002" integrator="Euler" density="{density}" viscosity="{viscosity}"
  wind="{wind}" gravity="0 0 0"/>
  <worldbody><body name="blade" pos="0 0 1"><joint name="hinge" axis="0 1 0"/>
    <geom type="box" size=".2 .05 .1" pos=".3 0 0" euler="0 20 10" mass="1"/></body></worldbody>
</mujoco>"""


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize(
    "density, viscosity, wind",
    [(1000, 0, "0 0 0"), (0, 0.5, "0 0 0"), (1200, 0.1, "1 -2 0")],
    ids=["drag", "viscous", "both-with-wind"],
)
def test_fluid_forces_match_mujoco(tmp_path, density, viscosity, wind):
    """A blade spinning on a hinge through MuJoCo's inertia-box fluid, under the per-step terms: the fluid term's
    link forces equal MuJoCo's qfrc_fluid (one step from 2 rad/s: 1e-8 to 5e-8 rad/s on a 4e-3 to 4e-2 change).
    Mutation: fluid dropped. A tree of several bodies, where each body's velocity is MuJoCo's cvel moved from the
    tree's centre of mass to its own: tests/test_loader_momentum.py::test_drag_turning_a_robot_in_a_fluid_is_carried."""
    path = mjcf_file(tmp_path, FLUID.format(density=density, viscosity=viscosity, wind=wind), "fluid.xml")

    def first_step(keep: bool) -> float:
        result = MJCFLoader().load(path)
        if not keep:
            result.controller.without("fluid")
        model = result.model
        return float(one_step(result, model, model.qpos0, np.full(model.nv, 2.0)).max())

    assert first_step(keep=True) < 1e-6
    assert first_step(keep=False) > 1e-4


GRAVCOMP = """<mujoco><option timestep="0.002"/>
  <worldbody><body name="upper" pos="0 0 1" gravcomp="{upper}"><joint name="shoulder" axis="0 1 0" damping="0.05"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
    <body name="lower" pos=".3 0 0" gravcomp="{lower}"><joint name="elbow" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/></body></body></worldbody>
</mujoco>"""


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("upper, lower", [(1, 1), (0.5, 1), (1, 1.5)], ids=["full", "half", "over"])
def test_gravity_compensation_matches_mujoco(tmp_path, monkeypatch, upper, lower):
    """An arm whose links compensate gravity fully (PhysX gravity off for the link), partly or more than fully
    (a per-step force at the centre of mass): 1.6e-15, 1.5e-6, 8.7e-7 rad over 1 s. Mutation: the loader ignoring
    gravcomp (the arm falls)."""
    path = mjcf_file(tmp_path, GRAVCOMP.format(upper=upper, lower=lower), "gravcomp.xml")
    result = MJCFLoader().load(path)
    assert replay(result, result.model, no_ctrl, 1.0).max() < SERVO_TOLERANCE
    import loader.runtime.controller

    monkeypatch.setattr(loader.runtime.controller, "map_gravcomp", lambda *args: None)  # planned at load
    ignored = MJCFLoader().load(path)
    assert replay(ignored, ignored.model, no_ctrl, 1.0).max() > 10 * SERVO_TOLERANCE


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("flags", ['spring="disable"', 'damper="disable"', 'spring="disable" damper="disable"'])
def test_spring_and_damper_flags_are_honoured(tmp_path, monkeypatch, flags):
    """<flag spring/damper="disable"/> turns joint and tendon springs/dampers off in MuJoCo; the loader too.
    Mutation: flags ignored (the springs and dampers mapped anyway)."""
    path = tmp_path / "flags.xml"
    path.write_text(f"""<mujoco><option timestep="0.002"><flag {flags}/></option>
      <worldbody><body pos="0 0 1"><joint name="a" axis="0 1 0" stiffness="3" springref="0.5" damping="0.2"/>
        <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/></body>
        <body pos="0 1 1"><joint name="b" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"
          mass=".5"/></body></worldbody>
      <tendon><fixed stiffness="2" damping="0.3"><joint joint="a" coef="1"/><joint joint="b" coef="-1"/></fixed>
      </tendon></mujoco>""")
    result = MJCFLoader().load(path)
    assert replay(result, result.model, no_ctrl, 1.0).max() < SERVO_TOLERANCE
    import loader.model.mj

    monkeypatch.setattr(loader.model.mj, "disabled", lambda model, *flags: False)  # the fixture sets no other flag
    blind = MJCFLoader().load(path)
    assert replay(blind, blind.model, no_ctrl, 1.0).max() > 10 * SERVO_TOLERANCE


TENDON_ROWS = """<mujoco><option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody><site name="anchor" pos="0 0 1.5"/>
    <body name="a" pos="0 0 1"><joint name="a" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"
      mass=".4"/><site name="tip" pos=".3 0 0"/></body>
    <body name="b" pos="0 1 1"><joint name="b" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".02"
      mass=".4"/></body></worldbody>
  <tendon><fixed name="rough" frictionloss="0.2" limited="true" range="-0.4 0.4">
      <joint joint="a" coef="1"/><joint joint="b" coef="-1"/></fixed>
    <spatial name="tether" limited="true" range="0 0.55"><site site="anchor"/><site site="tip"/></spatial></tendon>
  <keyframe><key qpos="0.3 -0.05" qvel="2 -1"/></keyframe>
</mujoco>"""
TENDON_ROWS_TOLERANCE = 1e-5  # rad over 1 s, measured 5.4e-7; rows off: 3.0 (mujoco 3.17.0, sapien 3.0.3)


def test_tendon_frictionloss_and_limits_are_mujocos_rows(tmp_path):
    """A fixed tendon with frictionloss and a length range over two hinges, and a spatial tether with a length
    limit: their rows are MuJoCo's own, solved at SAPIEN's state. Mutation: the rows term off."""
    path = mjcf_file(tmp_path, TENDON_ROWS, "tendon_rows.xml")

    def run(rows: bool) -> float:
        result = MJCFLoader().load(path)
        assert not [e for e in result.unsupported if e.kind == "tendon"], result.unsupported
        if not rows:
            result.controller.without("rows")
        return float(replay(result, result.model, no_ctrl, 1.0).max())

    assert run(rows=True) < TENDON_ROWS_TOLERANCE
    assert run(rows=False) > 100 * TENDON_ROWS_TOLERANCE


def test_a_springref_without_stiffness_is_no_spring():
    """MuJoCo applies no spring where the stiffness is zero, whatever the springref (an infinite one included):
    the arm swings under gravity exactly as MuJoCo's. Mutation: the spring target taken without the stiffness
    test is 0 * inf, a NaN drive and a NaN state at the first step (a robustness-session find)."""
    import warnings

    import mujoco

    from loader import MJCFLoader

    xml = (
        '<mujoco><worldbody><body pos="0 0 1"><joint name="a" axis="0 1 0" springref="-inf" damping=".1"/>'
        '<geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass="1"/></body></worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    for _ in range(100):
        mujoco.mj_step(model, data)
        result.step()
    qpos, _ = result.mapping.get_state(result.articulations)
    assert abs(data.qpos[0]) > 0.1  # it swung
    assert abs(qpos[0] - data.qpos[0]) < 1e-5
