"""The rows of DEFAULTS-CORNER-CASES.md as documents, each with the MuJoCo behaviour the row documents.

`CORNER_CASES` seeds the properties (as hypothesis `@example`s); `documented(case, model)` checks that MuJoCo
(the installed version) really behaves as the row says, so an example that stopped exercising its corner case
is noticed. Rows whose behaviour changed between MuJoCo versions (A4-A6, A13) carry the expectation of the
installed version.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from .document import RawDocument

MUJOCO_VERSION = tuple(int(x) for x in mujoco.__version__.split(".")[:2])
NEW_SHORTCUTS = MUJOCO_VERSION >= (3, 16)  # actuator shortcut defaults stopped feeding each other in 3.16

TETRA = "v 0 0 0\nv 0.2 0 0\nv 0 0.3 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


@dataclass(frozen=True)
class CornerCase:
    row: str
    document: RawDocument
    expect: Callable[[mujoco.MjModel], None] | None = None  # None: MuJoCo must reject the document


def _doc(row: str, body: str, files: dict[str, str] | None = None) -> RawDocument:
    return RawDocument(f'<mujoco model="row{row}">\n{body.strip()}\n</mujoco>\n', files or {}, label=f"row {row}")


def _geom(m: mujoco.MjModel, name: str):
    return m.geom(name)


def _is(actual, expected, what: str) -> None:
    if not np.allclose(np.asarray(actual, dtype=float), np.asarray(expected, dtype=float), atol=1e-9):
        raise AssertionError(f"{what}: MuJoCo has {actual}, the row documents {expected}")


GRAY = (0.5, 0.5, 0.5, 1)
_J = '<body name="b"><joint name="j"/><geom size=".1"/></body>'  # an actuated hinge for the actuator rows


def _act(m, kp, bias, gear=1.0):
    _is(m.actuator_gainprm[0][0], kp, "gain")
    _is(m.actuator_biasprm[0][:3], bias, "bias")
    _is(m.actuator_gear[0][0], gear, "gear")


CORNER_CASES: list[CornerCase] = [
    CornerCase(
        "1",
        _doc("1", '<default><geom size=".3"/></default><worldbody><geom name="g" class="main"/></worldbody>'),
        lambda m: _is(_geom(m, "g").size[0], 0.3, "size"),
    ),
    CornerCase(
        "2", _doc("2", '<default class="x"><geom size=".3"/></default><worldbody><geom size=".1"/></worldbody>')
    ),
    CornerCase(
        "3",
        _doc(
            "3",
            '<default><geom size=".3"/></default><default><geom rgba="0 1 0 1"/></default>'
            '<worldbody><geom name="g"/></worldbody>',
        ),
        lambda m: (_is(_geom(m, "g").size[0], 0.3, "size"), _is(_geom(m, "g").rgba, (0, 1, 0, 1), "rgba")),
    ),
    CornerCase(
        "4",
        _doc(
            "4",
            '<default><geom rgba="0 1 0 1"/><default class="a"><geom size=".3"/></default>'
            '</default><worldbody><geom name="g" class="a"/></worldbody>',
        ),
        lambda m: (_is(_geom(m, "g").size[0], 0.3, "size"), _is(_geom(m, "g").rgba, (0, 1, 0, 1), "rgba")),
    ),
    CornerCase(
        "5",
        _doc(
            "5",
            '<default><default class="a"><geom size=".3"/></default><geom rgba="0 1 0 1"/>'
            '</default><worldbody><geom name="g" class="a"/></worldbody>',
        ),
        lambda m: (_is(_geom(m, "g").size[0], 0.3, "size"), _is(_geom(m, "g").rgba, (0, 1, 0, 1), "rgba")),
    ),
    CornerCase(
        "6",
        _doc(
            "6",
            '<default><geom rgba="0 1 0 1"/><default class="a"><geom size=".2"/>'
            '<default class="b"><geom type="box" size=".3 .4 .5"/></default></default></default>'
            '<worldbody><body name="b"><joint/><geom name="g" class="b"/></body></worldbody>',
        ),
        lambda m: (_is(_geom(m, "g").size, (0.3, 0.4, 0.5), "size"), _is(_geom(m, "g").rgba, (0, 1, 0, 1), "rgba")),
    ),
    CornerCase(
        "7",
        _doc(
            "7",
            '<default><default class="c"><geom size=".3"/></default></default><worldbody>'
            '<body name="b" childclass="c"><joint/><geom name="g1"/><body name="c">'
            '<joint/><geom name="g2"/></body></body></worldbody>',
        ),
        lambda m: _is([_geom(m, "g1").size[0], _geom(m, "g2").size[0]], [0.3, 0.3], "sizes"),
    ),
    CornerCase(
        "8",
        _doc(
            "8",
            '<default><geom size=".1"/><default class="c"><geom rgba="0 1 0 1"/></default>'
            '<default class="d"><geom size=".3"/></default></default><worldbody>'
            '<body childclass="c"><joint/><geom name="g" class="d"/></body></worldbody>',
        ),
        lambda m: (_is(_geom(m, "g").size[0], 0.3, "size"), _is(_geom(m, "g").rgba, GRAY, "rgba")),
    ),
    CornerCase(
        "9",
        _doc(
            "9",
            '<default><geom size=".2"/><default class="c"><geom size=".3"/></default></default>'
            '<worldbody><body childclass="c"><joint/><geom name="g" class="main"/></body></worldbody>',
        ),
        lambda m: _is(_geom(m, "g").size[0], 0.2, "size"),
    ),
    CornerCase(
        "10",
        _doc(
            "10",
            '<default><default class="c"><geom size=".1"/></default><default class="d">'
            '<geom size=".2"/></default></default><worldbody><body childclass="c"><joint/>'
            '<geom name="g1"/><body childclass="d"><joint/><geom name="g2"/><body><joint/>'
            '<geom name="g3"/></body></body></body></worldbody>',
        ),
        lambda m: _is([_geom(m, n).size[0] for n in ("g1", "g2", "g3")], [0.1, 0.2, 0.2], "sizes"),
    ),
    CornerCase(
        "11",
        _doc(
            "11",
            '<default><default class="c"><geom size=".3 .3 .3" type="box"/></default>'
            '</default><worldbody><body><joint/><frame childclass="c" euler="0 0 30"><geom name="g1"/></frame>'
            '<geom name="g2" size=".1"/></body></worldbody>',
        ),
        lambda m: (
            _is(m.geom_type[_geom(m, "g1").id], mujoco.mjtGeom.mjGEOM_BOX, "type"),
            _is(m.geom_type[_geom(m, "g2").id], mujoco.mjtGeom.mjGEOM_SPHERE, "type"),
        ),
    ),
    CornerCase(
        "12a",
        _doc("12a", '<default><default class="c"/></default><worldbody childclass="c"><geom size=".1"/></worldbody>'),
    ),
    CornerCase(
        "12b",
        _doc(
            "12b",
            '<default><default class="c"/></default><worldbody><body class="c"><geom size=".1"/></body></worldbody>',
        ),
    ),
    CornerCase(
        "13",
        _doc(
            "13",
            '<default><default class="c"><joint damping="2"/><site size=".2"/></default>'
            '</default><worldbody><body childclass="c"><joint name="j"/><site name="s"/>'
            '<geom size=".1"/></body></worldbody>',
        ),
        lambda m: (
            _is(m.dof_damping[m.joint("j").dofadr[0]], 2, "damping"),
            _is(m.site("s").size[0], 0.2, "site size"),
        ),
    ),
    CornerCase("14a", _doc("14a", '<worldbody><geom class="nope" size=".1"/></worldbody>')),
    CornerCase(
        "14b",
        _doc(
            "14b", '<default><default class="a"/><default class="a"/></default><worldbody><geom size=".1"/></worldbody>'
        ),
    ),
    CornerCase(
        "15",
        _doc(
            "15",
            '<default><default class="a"><geom size=".1"/><geom size=".2"/></default>'
            '</default><worldbody><geom size=".1"/></worldbody>',
        ),
    ),
    CornerCase("16a", _doc("16a", '<default><geom name="x" size=".1"/></default><worldbody><geom/></worldbody>')),
    CornerCase("16b", _doc("16b", '<default><body/></default><worldbody><geom size=".1"/></worldbody>')),
    CornerCase(
        "17",
        _doc(
            "17",
            '<default><geom type="box" size="1 2 3"/></default><worldbody><body><joint/>'
            '<geom name="g" size="5"/></body></worldbody>',
        ),
        lambda m: _is(_geom(m, "g").size, (5, 2, 3), "size"),
    ),
    CornerCase("17b", _doc("17b", '<worldbody><geom size=".1" rgba="0 1"/></worldbody>')),
    CornerCase(
        "18",
        _doc(
            "18",
            '<default><geom size=".1"/><default class="s"><geom type="capsule" size=".05" '
            'fromto="0 0 0 0 0 .4"/></default><default class="p"><geom pos=".1 .2 .3" '
            'euler="0 90 0"/></default></default><worldbody><body name="b"><joint/>'
            '<geom name="g" class="s"/><geom name="h" class="p"/></body></worldbody>',
        ),
        lambda m: (
            _is(_geom(m, "g").size[:2], (0.05, 0.2), "capsule size"),
            _is(_geom(m, "g").pos, (0, 0, 0.2), "capsule centre"),
            _is(_geom(m, "h").pos, (0.1, 0.2, 0.3), "default pos"),
        ),
    ),
    CornerCase(
        "19",
        _doc(
            "19",
            '<compiler angle="degree"/><default><joint range="-90 90"/></default><worldbody>'
            '<body><joint name="h" type="hinge"/><joint name="s" type="slide"/><geom size=".1"/>'
            "</body></worldbody>",
        ),
        lambda m: (
            _is(m.joint("h").range, (-np.pi / 2, np.pi / 2), "hinge range"),
            _is(m.joint("s").range, (-90, 90), "slide range"),
        ),
    ),
    CornerCase(
        "20",
        _doc(
            "20",
            '<compiler autolimits="true"/><default><joint range="-1 1"/><default class="u">'
            '<joint limited="false"/></default></default><worldbody><body><joint name="a"/>'
            '<joint name="b" class="u" range="-2 2"/><geom size=".1"/></body></worldbody>',
        ),
        lambda m: _is([m.jnt_limited[m.joint("a").id], m.jnt_limited[m.joint("b").id]], [1, 0], "limited"),
    ),
    CornerCase(
        "21",
        _doc(
            "21",
            '<default><joint type="slide"/></default><worldbody><body><joint name="j"/>'
            '<geom size=".1"/></body></worldbody>',
        ),
        lambda m: _is(m.jnt_type[0], mujoco.mjtJoint.mjJNT_SLIDE, "type"),
    ),
    CornerCase(
        "22",
        _doc(
            "22",
            '<default><joint damping="2" armature=".5"/></default><worldbody>'
            '<body name="f"><freejoint name="fj"/><geom size=".1"/></body><body name="t" pos="1 0 0">'
            '<joint name="tj" type="free"/><geom size=".1"/></body></worldbody>',
        ),
        lambda m: (
            _is(m.dof_damping[0:6], 0, "freejoint damping"),
            _is(m.dof_armature[0:6], 0, "freejoint armature"),
            _is(m.dof_damping[6:12], 2, "type=free damping"),
            _is(m.dof_armature[6:12], 0.5, "type=free armature"),
        ),
    ),
    CornerCase(
        "23",
        _doc(
            "23",
            '<default><geom size=".1" mass="2"/><default class="d"><geom density="1"/>'
            '</default></default><worldbody><body name="a"><joint/><geom density="1"/></body>'
            '<body name="b"><joint/><geom class="d" mass="2"/></body></worldbody>',
        ),
        lambda m: _is(m.body_mass[1:3], (2, 2), "mass"),
    ),
    CornerCase(
        "24",
        _doc(
            "24",
            '<default><geom rgba="0 1 0 1" size=".1"/></default><asset><material name="m" '
            'rgba="1 0 0 1"/></asset><worldbody><geom name="g" material="m"/></worldbody>',
        ),
        lambda m: _is(_geom(m, "g").rgba, (0, 1, 0, 1), "rgba"),
    ),
    CornerCase(
        "25",
        _doc(
            "25",
            '<default><material rgba="0 0 1 1" specular=".9"/></default><asset>'
            '<material name="m"/></asset><worldbody><geom size=".1" material="m"/></worldbody>',
        ),
        lambda m: (_is(m.mat_rgba[0], (0, 0, 1, 1), "material rgba"), _is(m.mat_specular[0], 0.9, "specular")),
    ),
    CornerCase(
        "26",
        _doc(
            "26",
            '<default><mesh scale="2 2 2"/></default><asset><mesh name="t" file="t.obj"/>'
            '</asset><worldbody><body><joint/><geom type="mesh" mesh="t"/></body></worldbody>',
            {"t.obj": TETRA},
        ),
        lambda m: _is(m.mesh_scale[0], (2, 2, 2), "mesh scale"),
    ),
    CornerCase(
        "27",
        _doc(
            "27",
            '<default><default class="s"><mesh scale="3 3 3"/><geom type="mesh"/></default>'
            '</default><asset><mesh name="t" file="t.obj"/></asset><worldbody><body><joint/>'
            '<geom class="s" mesh="t"/></body></worldbody>',
            {"t.obj": TETRA},
        ),
        lambda m: _is(m.mesh_scale[0], (1, 1, 1), "mesh scale"),
    ),
    CornerCase(
        "28",
        _doc(
            "28",
            '<asset><mesh name="t" file="t.obj"/></asset><worldbody><body><joint/>'
            '<geom name="a" mesh="t"/><geom name="b" type="box" mesh="t"/></body></worldbody>',
            {"t.obj": TETRA},
        ),
        lambda m: (
            _is(m.geom_type[0], mujoco.mjtGeom.mjGEOM_SPHERE, "fitted type"),
            _is(m.geom_type[1], mujoco.mjtGeom.mjGEOM_BOX, "fitted type"),
        ),
    ),
    CornerCase(
        "29",
        _doc(
            "29",
            '<default><site size=".2"/><tendon stiffness="3"/><equality active="false"/>'
            '</default><worldbody><body><joint name="a"/><joint name="b"/><geom size=".1"/>'
            '<site name="s"/></body></worldbody><tendon><fixed name="t"><joint joint="a" coef="1"/>'
            '</fixed></tendon><equality><joint joint1="a" joint2="b"/></equality>',
        ),
        lambda m: (
            _is(m.site("s").size[0], 0.2, "site size"),
            _is(m.tendon_stiffness[0], 3, "tendon"),
            _is(m.eq_active0[0], 0, "equality active"),
        ),
    ),
    CornerCase(
        "A1",
        _doc(
            "A1",
            f'<default><general gainprm="7"/></default><worldbody>{_J}</worldbody>'
            '<actuator><position joint="j"/></actuator>',
        ),
        lambda m: _act(m, 7, (0, -7, 0)),
    ),
    CornerCase(
        "A2",
        _doc(
            "A2",
            f'<default><position kp="50" kv="2"/></default><worldbody>{_J}</worldbody>'
            '<actuator><general joint="j"/></actuator>',
        ),
        lambda m: (_act(m, 50, (0, -50, -2)), _is(m.actuator_biastype[0], mujoco.mjtBias.mjBIAS_AFFINE, "biastype")),
    ),
    CornerCase(
        "A3",
        _doc(
            "A3",
            f'<default><general gainprm="5" gear="3"/></default><worldbody>{_J}</worldbody>'
            '<actuator><motor joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, 0, 0), gear=3),
    ),
    CornerCase(
        "A4",
        _doc(
            "A4",
            f'<default><velocity kv="7"/></default><worldbody>{_J}</worldbody>'
            '<actuator><position joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, -1, 0)) if NEW_SHORTCUTS else _act(m, 7, (0, -7, -7)),
    ),
    CornerCase(
        "A5",
        _doc(
            "A5",
            '<default><position kp="5"/><velocity kv="3"/></default>'
            f'<worldbody>{_J}</worldbody><actuator><position joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, -1, 0)) if NEW_SHORTCUTS else _act(m, 3, (0, -3, -3)),
    ),
    CornerCase(
        "A6",
        _doc(
            "A6",
            f'<default><position kp="50" kv="2"/></default><worldbody>{_J}</worldbody>'
            '<actuator><motor joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, 0, 0)) if NEW_SHORTCUTS else None,
    ),
    CornerCase(
        "A7",
        _doc(
            "A7",
            f'<default><position kp="3" kv="4"/></default><worldbody>{_J}</worldbody>'
            '<actuator><position joint="j" kp="10"/></actuator>',
        ),
        lambda m: _act(m, 10, (0, -10, -4)),
    ),
    CornerCase(
        "A8",
        _doc(
            "A8",
            '<compiler autolimits="true"/><default><default class="p"><position '
            f'ctrlrange="-1 1"/></default></default><worldbody>{_J}</worldbody><actuator>'
            '<position class="p" joint="j"/></actuator>',
        ),
        lambda m: (_act(m, 1, (0, -1, 0)), _is(m.actuator_ctrllimited[0], 1, "ctrllimited")),
    ),
    CornerCase(
        "A9",
        _doc(
            "A9",
            f'<default><motor gear="5"/></default><worldbody>{_J}</worldbody>'
            '<actuator><position joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, -1, 0), gear=5),
    ),
    CornerCase(
        "A10",
        _doc(
            "A10",
            '<compiler angle="radian"/><default><position inheritrange="1"/></default><worldbody><body>'
            '<joint name="j" range="-0.5 0.7"/><geom size=".1"/></body></worldbody><actuator>'
            '<position joint="j"/></actuator>',
        ),
        lambda m: _is(m.actuator_ctrlrange[0], (-0.5, 0.7), "ctrlrange"),
    ),
    CornerCase(
        "A11",
        _doc(
            "A11",
            f'<default><position kp="10" dampratio="1"/></default><worldbody>{_J}'
            '</worldbody><actuator><position joint="j"/></actuator>',
        ),
        lambda m: (
            _is(m.actuator_gainprm[0][0], 10, "kp"),
            _is(m.actuator_biasprm[0][2] < 0, True, "kv computed from the damping ratio"),
        ),
    ),
    CornerCase(
        "A12",
        _doc(
            "A12",
            '<default><default class="c"><position kp="99"/></default></default><worldbody>'
            '<body childclass="c"><joint name="j"/><geom size=".1"/></body></worldbody><actuator>'
            '<position joint="j"/></actuator>',
        ),
        lambda m: _act(m, 1, (0, -1, 0)),
    ),
    CornerCase(
        "A13",
        _doc(
            "A13",
            '<default><intvelocity kp="4" actrange="-1 1"/></default>'
            f'<worldbody>{_J}</worldbody><actuator><position joint="j"/></actuator>',
        ),
        None if NEW_SHORTCUTS else (lambda m: _is(m.actuator_gainprm[0][0], 4, "kp")),
    ),
]


def documented(case: CornerCase, model: mujoco.MjModel | None, error: str | None) -> None:
    """Assert that MuJoCo's outcome (`model`, or `error` when it rejected the document) is the row's."""
    if case.expect is None:
        if model is not None:
            raise AssertionError(
                f"row {case.row}: MuJoCo {mujoco.__version__} accepts the document, the row documents an error"
            )
        return
    if model is None:
        raise AssertionError(f"row {case.row}: MuJoCo {mujoco.__version__} rejects the document: {error}")
    case.expect(model)
