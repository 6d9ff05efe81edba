"""ManiSkill's MJCF dialect and names without ManiSkill: a file written for ManiSkill's own loader (a fixed joint, a
sensor on a site it never defines) loads with a note, and links are named as that loader names them while
the robot moves as MuJoCo's. The names are checked against ManiSkill's loader itself in tests/test_maniskill.py."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest
from support.corpus import mjcf_file
from support.lockstep import paired_rollout

from loader import MJCFError, MJCFLoader

FIXED = """<mujoco model="legged"><option timestep="0.002"/>
  <worldbody><geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 1"><joint name="hip" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
      <body name="foot" pos="0.3 0 0"><joint name="weld" type="fixed"/><geom type="sphere" size="0.05"/></body>
    </body>
  </worldbody>
  <sensor><touch name="contact" site="toe"/></sensor>
</mujoco>"""

# Two world children: a fixed arm whose root has no joint, then a free torso whose first child carries two joints.
NAMED = """<mujoco model="named"><option timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <body name="base" pos="0 0 0.5"><geom type="box" size="0.1 0.1 0.1" mass="2"/>
      <body name="upper" pos="0 0 0.2"><joint name="shoulder" axis="0 1 0" damping="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/></body>
    </body>
    <body name="torso" pos="1 0 1"><freejoint name="root"/><geom type="box" size="0.2 0.1 0.05" pos="0.05 0 0"/>
      <body name="thigh" pos="0.2 0 0"><joint name="hip_x" axis="1 0 0"/><joint name="hip_y" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.04"/></body>
    </body>
  </worldbody>
</mujoco>"""
MANISKILL_LINKS = [
    ["dummy_root_0", "base", "upper"],
    ["dummy_root_1", "torso", "thigh_dummy_0", "thigh"],
]
# rad, the largest |SAPIEN - MuJoCo| joint position over 0.5 s of NAMED contact-free from a kick, either naming:
# measured 3.5e-6 with MuJoCo's names and 3.8e-6 with ManiSkill's (mujoco 3.17.0, sapien 3.0.3); a dummy root of
# 1 kg at the torso's origin instead of the helper's mass at its centre: 3.0e-3
NAMES_TOLERANCE = 1e-5


def _load(path, dialect=True):
    loader = MJCFLoader()
    loader.maniskill_dialect = dialect
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return loader.load(path)


def test_a_fixed_joint_welds_its_body_and_a_sensor_on_nothing_is_dropped(tmp_path):
    result = _load(mjcf_file(tmp_path, FIXED))
    (art,) = result.articulations
    assert [j.name for j in art.active_joints] == ["hip"]
    foot = next(link for link in art.links if link.name == "foot")
    assert foot.joint.type == "fixed" and foot.parent.name == "base"
    assert [(n.kind, n.name) for n in result.approximations if n.kind == "joint"] == [("joint", "weld")]
    assert [(n.kind, n.name) for n in result.unsupported] == [("sensor", "contact")]
    # welded, the foot keeps its place on the base as the hip turns
    art.set_qpos(np.array([0.7], np.float32))
    offset = foot.parent.entity_pose.inv() * foot.entity_pose
    np.testing.assert_allclose(offset.p, [0.3, 0, 0], atol=1e-6)


def test_a_fixed_joint_keeps_the_documents_includes_and_a_sensor_on_a_real_site(tmp_path):
    (tmp_path / "parts").mkdir()
    mjcf_file(
        tmp_path / "parts", '<mujoco><asset><material name="steel" rgba="0.5 0.5 0.5 1"/></asset></mujoco>', "a.xml"
    )
    text = FIXED.replace('<option timestep="0.002"/>', '<include file="parts/a.xml"/>')
    text = text.replace('<geom type="sphere" size="0.05"/>', '<geom type="sphere" size="0.05" material="steel"/>')
    text = text.replace('<touch name="contact" site="toe"/>', '<touch name="contact" site="tip"/>')
    text = text.replace('<body name="foot" pos="0.3 0 0">', '<body name="foot" pos="0.3 0 0"><site name="tip"/>')
    result = _load(mjcf_file(tmp_path, text))
    assert result.model.nmat == 1 and result.model.nsensor == 1
    assert not result.unsupported


def test_a_fixed_joint_in_an_included_file_stays_mujocos_error(tmp_path):
    body = '<mujoco><worldbody><body name="b"><joint type="fixed"/><geom size="0.1"/></body></worldbody></mujoco>'
    mjcf_file(tmp_path, body, "part.xml")
    with pytest.raises(MJCFError, match="fixed"):
        _load(mjcf_file(tmp_path, '<mujoco><include file="part.xml"/></mujoco>'))


def test_without_the_dialect_mujocos_rejections_stand(tmp_path):
    with pytest.raises(MJCFError, match="fixed"):
        _load(mjcf_file(tmp_path, FIXED), dialect=False)
    with pytest.raises(MJCFError, match="toe"):
        _load(mjcf_file(tmp_path, FIXED.replace('<joint name="weld" type="fixed"/>', "")), dialect=False)


def test_a_spec_with_a_sensor_on_nothing_is_refused_not_edited(tmp_path):
    spec = mujoco.MjSpec.from_string(FIXED.replace('<joint name="weld" type="fixed"/>', ""))
    with pytest.raises(MJCFError, match="toe"):
        _load(spec)
    assert len(spec.sensors) == 1


def test_maniskill_names_name_roots_and_helper_links_as_maniskills_loader(tmp_path):
    path = mjcf_file(tmp_path, NAMED)
    ours = _load(path, dialect=False)
    assert [[link.name for link in art.links] for art in ours.articulations] == [
        ["base", "upper"],
        ["torso", "thigh:hip_x", "thigh"],
    ]
    named = _load(path)
    assert [[link.name for link in art.links] for art in named.articulations] == MANISKILL_LINKS
    assert [[j.name for j in art.active_joints] for art in named.articulations] == [["shoulder"], ["hip_x", "hip_y"]]
    assert named.articulations[1].root.joint.type == "undefined"  # floating, the torso welded to it


def test_a_wrapper_bodys_link_takes_the_root_name(tmp_path):
    wrapped = NAMED.replace('<body name="base" pos="0 0 0.5">', '<body name="mount"><body name="base" pos="0 0 0.5">')
    wrapped = wrapped.replace("</body>\n    </body>\n    <body", "</body>\n    </body></body>\n    <body", 1)
    named = _load(mjcf_file(tmp_path, wrapped))
    assert [link.name for link in named.articulations[0].links] == MANISKILL_LINKS[0]


@pytest.mark.parametrize("dialect", [False, True])
def test_maniskill_names_move_as_mujoco(tmp_path, dialect):
    result = _load(mjcf_file(tmp_path, NAMED), dialect)
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    data.qvel[:] = np.linspace(-1.0, 1.0, model.nv)
    result.set_state(data.qpos, data.qvel)
    paired = paired_rollout(result, model, data, 250)
    assert paired.qpos.max() < NAMES_TOLERANCE
