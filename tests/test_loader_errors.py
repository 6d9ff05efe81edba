"""Bad input becomes one typed error that names the file, the line and what to do."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from support.corpus import FIXTURES, suite_path

from loader import MissingAssetError, MJCFError, MJCFLoader


def test_missing_mesh_is_a_missing_asset_error_naming_the_file():
    with pytest.raises(MissingAssetError) as error:
        MJCFLoader().load(FIXTURES / "missing_mesh.xml")
    assert "no_such_mesh.stl" in str(error.value)
    assert error.value.file.endswith("missing_mesh.xml")


def test_malformed_xml_names_the_line():
    with pytest.raises(MJCFError) as error:
        MJCFLoader().load(FIXTURES / "malformed.xml")
    assert error.value.line is not None
    assert "malformed.xml" in str(error.value) and "fix:" in str(error.value)


def test_unknown_default_class_is_rejected_with_mujocos_message():
    with pytest.raises(MJCFError) as error:
        MJCFLoader().parse(FIXTURES / "unknown_class.xml")
    assert "nope" in error.value.mujoco_message
    assert error.value.line == 5 and error.value.element == "geom"


def test_a_path_that_is_not_a_file():
    """A missing file, a folder and a document passed as text each say what they are and the fix, without blaming
    MuJoCo (which was never asked) and without echoing the document."""
    with pytest.raises(MJCFError) as missing:
        MJCFLoader().load("franka_emika_panda/panda.xml")
    assert str(missing.value).startswith("franka_emika_panda/panda.xml: no such file: nothing at this path (relative")
    assert "python -m conformance where NAME" in str(missing.value) and "MuJoCo" not in str(missing.value)
    with pytest.raises(MJCFError) as folder:
        MJCFLoader().load(FIXTURES)
    assert (
        str(folder.value) == f"{FIXTURES}: the loader takes a file: it is a folder\n  fix: pass the model's .xml file"
    )
    document = "<mujoco><worldbody><body><joint/><geom size='.1'/></body></worldbody></mujoco>"
    with pytest.raises(MJCFError) as text:
        MJCFLoader().load(document)
    assert str(text.value) == (
        "<string>: the loader takes a file: an MJCF document was passed as text\n"
        "  fix: pass a path or an MjSpec; for a string use mujoco.MjSpec.from_string(text)"
    )


def test_an_unknown_keyframe_is_a_control_error_naming_the_keyframes():
    """`reset(key)` with a keyframe the model lacks raises ControlError listing the model's keyframes (none here),
    before anything changes."""
    from loader import ControlError

    result = MJCFLoader().load(mujoco.MjSpec.from_string(KEYED.split("<keyframe>")[0] + "</mujoco>"))
    before = result.get_state()
    with pytest.raises(ControlError, match=r"no keyframe 'home'; the model's keyframes: none"):
        result.reset("home")
    keyed = MJCFLoader().load(mujoco.MjSpec.from_string(KEYED))
    with pytest.raises(ControlError, match=r"no keyframe 'away'; the model's keyframes: 'home', 'bent'"):
        keyed.reset("away")
    assert all(np.array_equal(a, b) for a, b in zip(before, result.get_state()))


KEYED = """<mujoco><worldbody><body><joint name="hinge"/><geom size=".1" mass="1"/></body></worldbody>
  <keyframe><key name="home" qpos="0"/><key name="bent" qpos="0.5"/></keyframe></mujoco>"""


ARM = """<mujoco><option timestep="0.002"/><worldbody><body name="arm" pos="0 0 1">
  <joint name="hinge" axis="0 1 0" damping="0.1"/>
  <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".3"/></body></worldbody>
  <actuator><position joint="hinge" kp="5" kv="0.2"/><general joint="hinge" dyntype="filter" dynprm="0.05"/>
  </actuator></mujoco>"""


def _arm_state(result) -> tuple:
    import numpy as np

    art, joint = result.articulations[0], result.articulations[0].active_joints[0]
    return (
        np.array(art.qf),
        float(joint.drive_target[0]),
        float(joint.drive_velocity_target[0]),
        result.act.copy(),
        np.array(art.qpos),
        np.array(art.qvel),
    )


@pytest.mark.parametrize(
    "ctrl,qfrc,message",
    [
        ([0.3], None, r"ctrl has shape \(1,\); the model has 2 actuators"),
        ([0.3, 0.1, 0.0], None, "ctrl has shape"),
        ([float("nan"), 0.1], None, r"ctrl\[0\] is nan"),
        ([0.3, float("inf")], None, r"ctrl\[1\] is inf"),
        ([2e10, 0.1], None, r"ctrl\[0\] is 2e\+10: MuJoCo refuses"),  # MuJoCo zeroes it as unstable
        ([0.3, 0.1], [float("nan")], r"qfrc_applied\[0\] is nan"),
        ([0.3, 0.1], [1.0, 2.0], r"qfrc_applied has shape \(2,\); the model has 1 DoFs"),
    ],
)
def test_a_bad_command_is_a_control_error_and_changes_nothing(ctrl, qfrc, message):
    import mujoco
    import numpy as np

    from loader import ControlError

    result = MJCFLoader().load(mujoco.MjSpec.from_string(ARM))
    result.set_ctrl([0.5, 1.0])
    result.scene.step()
    result.set_ctrl([0.5, 1.0])
    before = _arm_state(result)
    with pytest.raises(ControlError, match=message) as error:
        result.set_ctrl(ctrl, qfrc_applied=qfrc)
    assert str(error.value).startswith(result.path)
    with pytest.raises(ControlError):
        result.step(ctrl, qfrc_applied=qfrc)
    after = _arm_state(result)
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    result.scene.step()  # the rejected commands reached nothing PhysX steps
    assert np.isfinite(result.articulations[0].qvel).all()


UNHOLDABLE = (
    '<mujoco><option timestep="{timestep}" tolerance="{tolerance}"/>'
    '<worldbody><body name="arm" pos="{pos}" gravcomp="{gravcomp}">'
    '<joint name="hinge" axis="0 1 0" damping="{damping}" ref="{ref}" margin="{margin}" range="{range}"/>'
    '<geom name="rod" type="capsule" fromto="0 0 0 .3 0 0" size="{size}" mass="1"/></body></worldbody>'
    "</mujoco>"
)
HOLDABLE = {
    "pos": "0 0 1",
    "damping": "0.1",
    "size": ".02",
    "ref": "0",
    "gravcomp": "0",
    "timestep": "0.002",
    "tolerance": "1e-8",
    "margin": "0",
    "range": "-3 3",
}


@pytest.mark.parametrize(
    "field, value, element, message",
    [
        ("pos", "1e30 0 0", "body 'arm'", "body_pos .* is beyond"),  # MuJoCo compiles it silently
        ("damping", "nan", "joint 'hinge'", "dof_damping .* is non-finite"),  # MuJoCo warns only
        ("damping", "1e39", "joint 'hinge'", r"is beyond 1e\+15"),
        ("damping", "1e16", "joint 'hinge'", r"is beyond 1e\+15"),  # times a gain, a float32 overflow
        ("size", "2e7", "geom 'rod'", "geom_size .* is beyond"),
        ("ref", "1e30", "joint 'hinge'", r"qpos0 \(ref\) .* is beyond 10000 rad"),  # float32 holds no angle there
        ("gravcomp", "1e39", "body 'arm'", r"body_gravcomp .* is beyond 1e\+15"),
        ("timestep", "-1", "option 'timestep'", r"is not within \(0, 1\] s"),  # MuJoCo steps backwards
        ("timestep", "1e30", "option 'timestep'", r"is not within \(0, 1\] s"),  # float32 states overflow
        ("tolerance", "inf", "option 'tolerance'", "opt.tolerance .* is non-finite"),  # MuJoCo's solver stops at once
        ("margin", "1e30", "joint 'hinge'", "jnt_margin .* is beyond"),  # MuJoCo's own run reached 4e11 rad/s
        ("range", "-1e30 3", "joint 'hinge'", r"jnt_range .* is beyond 1e\+15"),  # an infinite end is open; this not
        ("range", "nan 3", "joint 'hinge'", "jnt_range .* is non-finite"),
    ],
)
def test_a_compiled_number_physx_cannot_hold_is_a_typed_error_naming_the_element(
    field, value, element, message, monkeypatch
):
    """A number MuJoCo compiles but PhysX's float32 cannot hold raises MJCFError naming the element and the field,
    before anything is built: a user's scene is left as it was. Mutation: the check skipped (the model loads
    silently wrong, or fails deep inside the mapping with another exception)."""
    import warnings

    import mujoco
    import sapien

    import loader.mjcf_loader
    from loader import MJCFError

    xml = UNHOLDABLE.format(**{**HOLDABLE, field: value})
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    before = len(scene.entities)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(MJCFError, match=message) as error:
            MJCFLoader().set_scene(scene).load(mujoco.MjSpec.from_string(xml))
        assert element in str(error.value) and "PhysX cannot hold" in str(error.value)
        assert len(scene.entities) == before
        MJCFLoader().set_scene(scene).load(mujoco.MjSpec.from_string(UNHOLDABLE.format(**HOLDABLE)))  # it can load
        monkeypatch.setattr(loader.mjcf_loader, "check_numbers", lambda model, path: None)
        outcome = "loaded silently"
        try:
            MJCFLoader().load(mujoco.MjSpec.from_string(xml))
        except MJCFError:
            outcome = "typed error"
        except Exception as other:  # noqa: BLE001 - an untyped failure deep in the mapping is what the check prevents
            outcome = type(other).__name__
        assert outcome != "typed error"


@pytest.mark.parametrize("iterations", ["0", "-1"])
def test_a_constraint_solver_without_iterations_is_a_typed_error(iterations, monkeypatch):
    """`<option iterations>` below 1 compiles in MuJoCo and leaves every constraint slack, which PhysX's limits and
    contacts cannot follow (a robustness-session find: a hand whose SAPIEN joints reached 2,127 rad/s). Mutation:
    the check skipped loads it silently."""
    import mujoco

    import loader.mjcf_loader

    xml = UNHOLDABLE.format(**HOLDABLE).replace("<option ", f'<option iterations="{iterations}" ')
    with pytest.raises(MJCFError, match="option 'iterations'.*no constraint force"):
        MJCFLoader().load(mujoco.MjSpec.from_string(xml))
    monkeypatch.setattr(loader.mjcf_loader, "check_numbers", lambda model, path: None)
    MJCFLoader().load(mujoco.MjSpec.from_string(xml))


def test_a_name_that_is_not_utf8_is_a_typed_error(tmp_path):
    """MuJoCo compiles a name of arbitrary bytes; Python cannot read it, so the load says which name, instead of a
    UnicodeDecodeError from deep inside (a robustness-session find). Mutation: the check removed."""
    path = tmp_path / "bytes.xml"
    path.write_bytes(b'<mujoco><worldbody><body name="arm\xae"><joint/><geom size=".1"/></body></worldbody></mujoco>')
    with pytest.raises(MJCFError, match="is not UTF-8 text") as caught:
        MJCFLoader().load(str(path))
    assert str(path) in str(caught.value) and "arm" in str(caught.value)


def test_a_model_mujoco_compiles_but_cannot_run_is_a_typed_error(tmp_path):
    """A model whose forward pass runs out of MuJoCo's arena (thousands of bodies in the default arena; here 200
    in an arena made small) compiles in MuJoCo but cannot run: the load names the file, says MuJoCo cannot run it
    and how to raise the arena, and raises no untyped mujoco.FatalError. With the arena raised (the fix the message
    gives) the same model loads. Mutation: the check removed is a FatalError here."""
    import mujoco

    bodies = "".join(f'<body pos="{i % 20 * 0.1} {i // 20 * 0.1} 1"><geom size=".02"/></body>' for i in range(200))
    path = tmp_path / "crowd.xml"
    path.write_text(f'<mujoco><size memory="20K"/><worldbody>{bodies}</worldbody></mujoco>')
    mujoco.MjModel.from_xml_path(str(path))  # MuJoCo compiles it
    with pytest.raises(MJCFError) as caught:
        MJCFLoader().load(str(path))
    text = str(caught.value)
    assert str(path) in text and "cannot run" in text and "<size memory" in text
    assert caught.value.line is None  # MuJoCo's source line is not the document's
    path.write_text(f'<mujoco><size memory="10M"/><worldbody>{bodies}</worldbody></mujoco>')
    assert MJCFLoader().load(str(path)).model.nbody == 201


def test_a_state_that_is_no_longer_finite_is_refused_naming_the_dof_and_the_step():
    """A NaN in SAPIEN's state (a diverged step) stops the next `set_ctrl` with DivergenceError naming the first DoF
    that is not finite and the physics steps run; nothing is written to PhysX. A call that begins no step (a setting
    rewritten) only clears `qf`. Mutation: the check skipped (the NaN steps on silently)."""
    from loader import DivergenceError

    result = MJCFLoader().load(suite_path("acrobot"))
    for _ in range(3):
        result.step(np.zeros(result.model.nu))
    articulation = result.articulations[0]
    articulation.set_qvel(np.array([0.0, np.nan], np.float32))
    with pytest.raises(DivergenceError, match=r"joint 'elbow' .* after 3 physics steps"):
        result.set_ctrl(np.zeros(result.model.nu))
    with pytest.raises(DivergenceError):
        result.step(np.zeros(result.model.nu))
    articulation.set_qf(np.ones(2, np.float32))
    result.disable_actuators()  # a setting rewritten, no step begun: it only clears qf
    np.testing.assert_array_equal(articulation.get_qf(), np.zeros(2))
    result.disable_actuators(False)
    articulation.set_qvel(np.zeros(2, np.float32))
    result.step(np.zeros(result.model.nu))  # finite again, it steps on


def test_the_finiteness_check_reads_a_huge_state_entry_by_entry():
    """`set_ctrl`'s check sums the state's squares first: a finite state whose squares overflow is read entry by
    entry and passes, and an inf or a NaN anywhere fails. Mutation: the sum alone would call 1e200 diverged."""
    from loader.runtime.controller import finite

    calm, huge = np.array([0.5, -2.0]), np.array([1e200, -1e200])
    assert finite(calm, calm) and finite(huge, calm) and finite(calm, huge)
    for bad in (np.inf, -np.inf, np.nan):
        assert not finite(np.array([0.5, bad]), calm) and not finite(calm, np.array([bad, 0.5]))
