"""The joint actuation law's plan (loader/plan/joint_actuation.py): its scope. The law itself and its ManiSkill mode
are tested in tests/test_maniskill_joint_actuation.py (the `maniskill` extra)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from loader.plan import joint_actuation
from loader.plan.joint_actuation import FLOATING_ROOT, FREE_JOINT_TERMS, OTHER_EQUALITIES, plan_joint_actuation

# every actuator kind of the law on hinges, a slide and a fixed tendon over two of them, with gears, clamps that
# bind (ctrlrange, forcerange and a joint's actuatorfrcrange), springs and dampers (the tendon's with a deadband);
# a filter, an integrator within its actrange and an exact filter acting early
ACTUATED = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><body name="a"><joint name="h1" axis="0 1 0" damping="0.3" stiffness="2" springref="0.2"
      actuatorfrcrange="-40 50"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/>
    <body name="b" pos=".3 0 0"><joint name="h2" axis="0 0 1" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".02" mass=".3"/>
      <body name="c" pos=".2 0 0"><joint name="s" type="slide" axis="1 0 0" stiffness="5" damping="1"/>
        <geom type="box" size=".03 .03 .03" mass=".2"/></body></body></body></worldbody>
  <tendon><fixed name="t" stiffness="8" damping="0.7" springlength="-0.02 0.03">
    <joint joint="h1" coef="0.5"/><joint joint="s" coef="-1"/></fixed></tendon>
  <actuator>
    <position joint="h1" kp="40" kv="3" gear="2" ctrlrange="-1 1" forcerange="-30 30"/>
    <velocity joint="h2" kv="5" ctrlrange="-2 2"/>
    <motor joint="h2" gear="0.5" ctrlrange="-1 1"/>
    <general joint="s" gainprm="7" biastype="affine" biasprm="0.5 -20 -2" forcerange="-3 4"/>
    <general tendon="t" gear="1.5" gainprm="3" biastype="affine" biasprm="0 -4 -1.5" forcerange="-2 2"/>
    <general joint="h2" dyntype="filter" dynprm="0.05" gainprm="2" biastype="affine" biasprm="0 0 -0.5"/>
    <general joint="s" dyntype="integrator" actlimited="true" actrange="-0.5 0.8" gainprm="4" ctrlrange="-1 1"/>
    <general joint="h1" dyntype="filterexact" dynprm="0.03" actearly="true" gainprm="1.5"/>
  </actuator></mujoco>"""
DOF_OF_JOINT = {0: 0, 1: 1, 2: 2}


SPATIAL = """<mujoco><worldbody><body><joint name="j"/><geom size=".1"/><site name="a" pos=".1 0 0"/></body>
  <site name="b" pos=".3 .2 0"/></worldbody>
  <tendon><spatial name="t"><site site="a"/><site site="b"/></spatial></tendon>
  <actuator><motor name="pull" tendon="t"/></actuator></mujoco>"""


def test_out_of_scope_actuators_are_named():
    """An actuator the law cannot carry is named with why: one on a spatial tendon (its moment changes with the
    pose), one with a muscle's activation dynamics."""
    why = plan_joint_actuation(mujoco.MjModel.from_xml_string(SPATIAL), {0: 0}, 1)
    assert isinstance(why, str) and "'pull'" in why and "spatial tendon" in why
    muscle = ACTUATED.format(integrator="implicitfast").replace(
        '<motor joint="h2" gear="0.5"', '<general name="m" dyntype="muscle" dynprm="0.01 0.04" joint="h2" gear="0.5"'
    )
    why = plan_joint_actuation(mujoco.MjModel.from_xml_string(muscle), DOF_OF_JOINT, 3)
    assert isinstance(why, str) and "'m'" in why and "activation" in why


def test_a_fixed_tendons_moment_is_its_gear_times_its_coefficients():
    """The fixed tendon actuator's moment over the robot's DoFs (here in reverse of MuJoCo's order) is its gear
    times the tendon's coefficients, as MuJoCo's transmission gives it."""
    model = mujoco.MjModel.from_xml_string(ACTUATED.format(integrator="implicitfast"))
    plan = plan_joint_actuation(model, {0: 2, 1: 1, 2: 0}, model.nv)
    (tendon,) = np.flatnonzero(model.actuator_trntype == mujoco.mjtTrn.mjTRN_TENDON)
    assert np.array_equal(plan.moment[tendon], [-1.5 * 1.0, 0.0, 1.5 * 0.5])  # gear 1.5; coef 0.5 on h1, -1 on s


def _velocity_derivative(model: mujoco.MjModel) -> np.ndarray:
    """d(qfrc_actuator + qfrc_passive)/d(qvel) at qpos0, zero velocity and ctrl, by central differences."""
    data, step, columns = mujoco.MjData(model), 1e-6, []
    for dof in range(model.nv):
        forces = []
        for sign in (1.0, -1.0):
            data.qvel[:] = 0.0
            data.qvel[dof] = sign * step
            mujoco.mj_forward(model, data)
            forces.append(data.qfrc_actuator + data.qfrc_passive)
        columns.append((forces[0] - forces[1]) / (2 * step))
    return np.array(columns).T


@pytest.mark.parametrize("mistake", [False, True], ids=["planned", "mistake_actuators_explicit"])
def test_the_drives_hold_mujocos_velocity_derivative_under_implicitfast(monkeypatch, mistake):
    """Under implicitfast MuJoCo integrates d(force)/d(qvel) implicitly: each DoF's joint damping and its actuators'
    kv m^2 on its diagonal (the fixed tendon's cross terms off it). The drives' damping is that diagonal, less its
    sign; planned as if implicitfast's actuators were explicit, it lacks the actuators' kv."""
    if mistake:
        implicitfast = int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST)
        monkeypatch.setattr(joint_actuation, "EXPLICIT_ACTUATORS", (*joint_actuation.EXPLICIT_ACTUATORS, implicitfast))
    model = mujoco.MjModel.from_xml_string(ACTUATED.format(integrator="implicitfast"))
    derivative = _velocity_derivative(model)
    assert not np.allclose(derivative, np.diag(np.diag(derivative)), atol=1e-6)  # the tendon couples h1 and s
    plan = plan_joint_actuation(model, DOF_OF_JOINT, model.nv)
    assert np.allclose(plan.drive_damping, -np.diag(derivative), atol=1e-6) != mistake


FLOATING = """<mujoco><worldbody><body name="root"><freejoint/><geom size=".1"/>
  <body name="arm"><joint name="j" axis="0 1 0" limited="true" range="-1 1"/><geom size=".05" pos=".2 0 0"/></body>
  </body></worldbody><equality><joint joint1="j"/></equality><actuator><motor joint="j"/></actuator></mujoco>"""


@pytest.mark.parametrize("flags", [(), ("limit", "equality"), ("constraint",)])
def test_what_the_law_leaves_out_is_named_and_a_disabled_row_is_not(flags):
    """A robot on a free joint names its floating root (PhysX's step where a contact pushed it); a connect from it to
    the world is named unless the model disables equalities (the law places a world end on a fixed root alone). Its
    joint limit and its joint coupling are carried (the law's rows) unless the model disables them."""
    disabled = " ".join(f'{flag}="disable"' for flag in flags)
    xml = FLOATING.replace("<worldbody>", f"<option><flag {disabled}/></option><worldbody>", 1)
    xml = xml.replace("</equality>", '<connect body1="arm" anchor="0 0 0"/></equality>')
    model = mujoco.MjModel.from_xml_string(xml)
    plan = plan_joint_actuation(model, {1: 0}, 1, {1: 0, 2: 1})
    assert FLOATING_ROOT in plan.not_carried
    assert (OTHER_EQUALITIES in plan.not_carried) == (not flags)
    assert bool(plan.limits.limited[0]) == (not flags)
    assert plan.couplings.first.shape[0] == (0 if flags else 1)
    fixed = plan_joint_actuation(model, {1: 0}, 1, {2: 0})  # the robot is the arm alone: no root of its own floats
    assert FLOATING_ROOT not in fixed.not_carried
    assert FREE_JOINT_TERMS not in plan.not_carried


@pytest.mark.parametrize("attribute", ["damping", "armature", "frictionloss"])
def test_a_free_joints_damping_armature_or_frictionloss_is_named(attribute):
    """The law's root rows hold none of them: a free joint with one is named."""
    model = mujoco.MjModel.from_xml_string(FLOATING.replace("<freejoint/>", f'<joint type="free" {attribute}="0.1"/>'))
    plan = plan_joint_actuation(model, {1: 0}, 1, {1: 0, 2: 1})
    assert FREE_JOINT_TERMS in plan.not_carried


# a hinge carrying two slides on separate branches (a gripper's fingers), one fixed tendon servo over both, the
# tendon sprung and damped
SIBLINGS = """<mujoco><option timestep="0.002" integrator="{integrator}"/>
  <worldbody><body name="hand"><joint name="h" axis="0 0 1" damping="0.2"/>
    <geom type="box" size=".05 .02 .02" mass=".6"/>
    <body name="left" pos="0 .03 0"><joint name="l" type="slide" axis="0 1 0" damping="1"/>
      <geom type="box" size=".01 .01 .03" mass=".02"/></body>
    <body name="right" pos="0 -.03 0"><joint name="r" type="slide" axis="0 -1 0" damping="1"/>
      <geom type="box" size=".01 .01 .03" mass=".02"/></body></body></worldbody>
  <tendon><fixed name="split" stiffness="5" damping="2"><joint joint="l" coef="0.5"/><joint joint="r" coef="0.5"/>
  </fixed></tendon>
  <actuator><position tendon="split" kp="100" kv="5" ctrlrange="0 .04" forcerange="-20 20"/>
    <motor joint="h" ctrlrange="-1 1"/></actuator></mujoco>"""


def _implicit_matrix(plan, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """The plan's D (the negated velocity derivative MuJoCo's step takes implicitly) at `data`: the implicit dampers,
    and each actuator's velocity gain and each tendon's implicit damper over the DoF pairs on one chain, but an
    actuator's on its forcerange."""
    low, high = plan.force_range
    free = (data.actuator_force > low) & (data.actuator_force < high)
    moment = plan.moment * (plan.velocity_gain * free)[:, None]
    springs = plan.springs
    tendons = (springs.moment.T * springs.implicit_damping) @ springs.moment
    return (moment.T @ plan.moment + tendons) * plan.chained + np.diag(plan.implicit_damping)


@pytest.mark.parametrize(
    "mistake", [None, "cross_terms_everywhere", "cross_terms_nowhere", "kv_explicit", "tendon_damper_explicit"]
)
@pytest.mark.parametrize("integrator", ["implicitfast", "Euler"])
@pytest.mark.parametrize("fixture", ["chain", "siblings"])
def test_the_planned_implicit_derivative_is_mujocos_step(fixture, integrator, mistake):
    """MuJoCo's step solves (M + dt D) (v1 - v0) = dt (f - c), and the plan's D gives its v1 (MuJoCo's M, f and c;
    random states, some binding a clamp): its dampers, and under implicitfast each actuator's -b2 m m^T and each
    tendon's damper d m m^T, whose cross terms MuJoCo keeps between DoFs on one chain (the chain's tendon over a
    hinge and a slide below it) and drops across branches (the fingers' tendon); under Euler a tendon's damper is
    explicit. Each mistake misses one fixture under one integrator at least: the cross terms everywhere (the
    fingers), nowhere (the chain), the actuators' kv or the tendons' dampers explicit (implicitfast)."""
    xml = (ACTUATED if fixture == "chain" else SIBLINGS).format(integrator=integrator)
    model = mujoco.MjModel.from_xml_string(xml)
    dofs = {j: j for j in range(model.njnt)}
    plan = plan_joint_actuation(model, dofs, model.nv)
    if mistake == "cross_terms_everywhere":
        plan.chained[:] = True
    elif mistake == "cross_terms_nowhere":
        plan.chained[:] = np.eye(model.nv, dtype=bool)
    elif mistake == "kv_explicit":
        plan.velocity_gain[:] = 0.0
    elif mistake == "tendon_damper_explicit":
        plan.springs.implicit_damping[:] = 0.0
    data, rng, worst = mujoco.MjData(model), np.random.default_rng(0), 0.0
    dense = np.zeros((model.nv, model.nv))
    for _ in range(16):
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:] = rng.uniform(-0.02, 0.02, model.nq), rng.uniform(-1, 1, model.nv)
        data.ctrl[:] = rng.uniform(*model.actuator_ctrlrange.T) * 0.2
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, dense)
        force = data.qfrc_actuator + data.qfrc_passive - data.qfrc_bias
        step = model.opt.timestep
        expected = data.qvel + np.linalg.solve(dense + step * _implicit_matrix(plan, model, data), step * force)
        mujoco.mj_step(model, data)
        worst = max(worst, float(np.abs(expected - data.qvel).max()))
    wrong = {
        "cross_terms_everywhere": fixture == "siblings" and integrator == "implicitfast",
        "cross_terms_nowhere": fixture == "chain" and integrator == "implicitfast",
        "kv_explicit": integrator == "implicitfast",
        "tendon_damper_explicit": integrator == "implicitfast",
    }.get(mistake, False)
    assert (worst > 1e-9) == wrong, worst


SPRUNG = "the springs and dampers of a nonlinear tendon, of one with armature or of a spatial one outside the law"


@pytest.mark.parametrize("tendon", ["fixed", "fixed_with_armature", "spatial"])
def test_a_fixed_tendons_spring_is_carried_and_any_other_is_named(tendon):
    """The chain's fixed tendon, sprung and damped, is in the law (its coefficients as its moment, its deadband) and
    not named; given armature, which M would have to hold, it leaves the law and is named; so is the spring of a
    spatial tendon the law cannot carry (SPATIAL's, sprung here, ends on the world body)."""
    if tendon == "spatial":
        spec = mujoco.MjSpec.from_string(SPATIAL)
        stiffness = np.array(spec.tendons[0].stiffness)
        stiffness[0] = 3.0
        spec.tendons[0].stiffness = stiffness
        model = spec.compile()
        plan = plan_joint_actuation(model, {0: 0}, 1)
        assert isinstance(plan, str)  # its actuator pulls the spatial tendon: outside the law, named
        assert SPRUNG in joint_actuation._not_carried(model, {}, {0: 0}, [])
        return
    spec = mujoco.MjSpec.from_string(ACTUATED.format(integrator="implicitfast"))
    if tendon == "fixed_with_armature":
        spec.tendons[0].armature = 0.1
    plan = plan_joint_actuation(spec.compile(), DOF_OF_JOINT, 3)
    carried = tendon == "fixed"
    assert (SPRUNG not in plan.not_carried) == carried
    assert plan.springs.stiffness.tolist() == ([8.0] if carried else [])
    if carried:
        assert plan.springs.moment.tolist() == [[0.5, 0.0, -1.0]] and plan.springs.rest.ravel().tolist() == [
            -0.02,
            0.03,
        ]


TENDON_ROWS_NAMED = (
    "the limits and frictionloss of a spatial tendon outside the law or of one over joints outside the robot"
)


@pytest.mark.parametrize("tendon", ["fixed", "spatial", "disabled"])
def test_a_fixed_tendons_limit_and_frictionloss_are_carried_and_a_spatial_ones_named(tendon):
    """The chain's fixed tendon, limited and with frictionloss, carries both rows on its length (its coefficients as
    its Jacobian, its range, its invweight0) and is not named; a spatial tendon's limit is named (SPATIAL's, its
    actuator taken out); with the model's limits and frictionloss disabled there is no row to carry or name."""
    if tendon == "spatial":
        spec = mujoco.MjSpec.from_string(SPATIAL)
        spec.delete(spec.actuators[0])
        spec.tendons[0].range, spec.tendons[0].limited = [0.1, 0.5], mujoco.mjtLimited.mjLIMITED_TRUE
        plan = plan_joint_actuation(spec.compile(), {0: 0}, 1)
        assert TENDON_ROWS_NAMED in plan.not_carried and not plan.tendon_rows.limits.limited.size
        return
    spec = mujoco.MjSpec.from_string(ACTUATED.format(integrator="implicitfast"))
    spec.tendons[0].range, spec.tendons[0].limited = [-0.2, 0.1], mujoco.mjtLimited.mjLIMITED_TRUE
    spec.tendons[0].frictionloss = 0.4
    if tendon == "disabled":
        spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_LIMIT | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    model = spec.compile()
    plan = plan_joint_actuation(model, DOF_OF_JOINT, 3)
    rows = plan.tendon_rows
    assert TENDON_ROWS_NAMED not in plan.not_carried
    if tendon == "disabled":
        assert rows.moment.shape == (0, 3)
        return
    assert rows.moment.tolist() == [[0.5, 0.0, -1.0]] and rows.limits.range.ravel().tolist() == [-0.2, 0.1]
    assert rows.friction.loss.tolist() == [0.4] and rows.limits.diag_approx.tolist() == [model.tendon_invweight0[0]]


@pytest.mark.parametrize("refsafe", [True, False])
def test_a_joint_limits_row_is_mujocos(refsafe):
    """The planned limit row's reference stiffness and damping (solreflimit with refsafe's floor of two timesteps,
    or the direct negative form) and its diagApprox are MuJoCo's own row's, read from MuJoCo's efc arrays at a state
    past the range: aref = -B J v - K imp (r - margin), R = (1 - imp) / imp diagApprox."""
    flag = "" if refsafe else '<flag refsafe="disable"/>'
    xml = f"""<mujoco><compiler angle="radian"/><option timestep="0.02">{flag}</option><worldbody><body>
      <joint name="a" axis="0 1 0" range="-0.5 0.5" solreflimit="0.01 0.7" margin="0.1"/><geom size=".1"/>
      <body pos=".3 0 0"><joint name="b" type="slide" range="-0.2 0.2" solreflimit="-300 -20"/><geom size=".1"/>
      </body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    limits = plan_joint_actuation(model, {0: 0, 1: 1}, 2).limits
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = [0.45, -0.3], [0.7, -1.1]  # hinge within its margin of the upper end, slide past
    mujoco.mj_forward(model, data)
    assert data.nefc == 2
    sign, distance = np.array([-1.0, 1.0]), np.array([0.5 - 0.45, -0.3 + 0.2])
    imp = data.efc_KBIP[:, 2]
    violation = distance - limits.margin
    aref = -limits.damping * sign * data.qvel - limits.stiffness * imp * violation
    np.testing.assert_allclose(aref, data.efc_aref, rtol=1e-12)
    np.testing.assert_allclose((1 - imp) / imp * limits.diag_approx, data.efc_R, rtol=1e-12)
