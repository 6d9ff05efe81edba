"""Documents of the classes real robots showed and the general generator missed: arms exported from URDF (frictionloss
with no armature and tiny damping on every joint), joints started past their ends (several at once, so that many limit
rows act together), ranges left open at one end or both (`inf`), tiny and zero inertias (dummy links, welded sensor
frames), gripper fingers coupled by a joint equality under position servos, a floating base and a tossed free object
whose free joints carry damping and armature (the base's frictionloss too), and MuJoCo Playground's solver setting of
one iteration; actuators on a site at the arm's tip (a wrench, or a servo on the tip's offset from a reference site)
and on the floating base's free joint; a muscle on the first hinge."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from .document import RawDocument

AXES = ("0 1 0", "0 0 1", "1 0 0")


def _f(x: float) -> str:
    return f"{round(x, 6):.4g}"  # no subnormals: MuJoCo's parser rejects them


@st.composite
def _link(draw, index: int) -> tuple[str, str, float, float, bool]:
    """A link's opening tags (body, joint, inertial), its joint name, range and whether it is a slide."""
    slide = draw(st.integers(0, 5)) == 5
    lo = draw(st.floats(-2.5, -0.1)) if not slide else draw(st.floats(-0.3, -0.02))
    hi = draw(st.floats(0.1, 2.5)) if not slide else draw(st.floats(0.02, 0.3))
    urdf = draw(st.booleans())  # an exported arm: frictionloss, tiny damping, no armature
    friction = _f(draw(st.floats(0.01, 1.0))) if urdf or draw(st.booleans()) else "0"
    damping = "0.001" if urdf else _f(draw(st.floats(0.0, 2.0)))
    armature = "0" if urdf else _f(draw(st.floats(0.0, 0.05)))
    kind = draw(st.sampled_from(["normal", "normal", "normal", "tiny"]))
    if kind == "tiny":  # a dummy link of an exported arm
        inertial = '<inertial pos="0 0 0" mass="1e-9" diaginertia="3e-13 3e-13 6e-13"/>'
    else:
        mass = draw(st.floats(0.1, 2.0))
        inertial = (
            f'<inertial pos="{_f(draw(st.floats(0.02, 0.15)))} 0 0" mass="{_f(mass)}" '
            f'diaginertia="{_f(mass * 1e-3)} {_f(mass * 4e-3)} {_f(mass * 4e-3)}"/>'
        )
    name = f"j{index}"
    ends = [_f(lo), _f(hi)]
    opened = draw(st.sampled_from(["closed"] * 4 + ["upper", "both"])) if not slide else "closed"
    if opened != "closed":  # a range left open (a wheel's "-inf inf", a door's "lo inf"): no limit that side
        ends = ["-inf" if opened == "both" else ends[0], "inf"]
        lo, hi = (-np.inf if opened == "both" else lo), np.inf
    joint = (
        f'<joint name="{name}" type="{"slide" if slide else "hinge"}" axis="{draw(st.sampled_from(AXES))}" '
        f'range="{" ".join(ends)}" frictionloss="{friction}" damping="{damping}" armature="{armature}"/>'
    )
    pos = f"{_f(draw(st.floats(0.1, 0.3)))} 0 0" if index else "0 0 1"
    return f'<body name="l{index}" pos="{pos}">{joint}{inertial}', name, lo, hi, slide


def _free_joint(draw, frictional: bool = False) -> str:
    """A free joint's damping, armature and, where `frictional`, frictionloss (each present half of the time), as
    attributes. A light tossed object gets no frictionloss: MuJoCo's own run of it then often fails (bad qacc)."""
    damping = _f(draw(st.floats(0.001, 0.5))) if draw(st.booleans()) else "0"
    armature = _f(draw(st.floats(0.001, 0.05))) if draw(st.booleans()) else "0"
    friction = _f(draw(st.floats(0.001, 0.05))) if frictional and draw(st.booleans()) else "0"
    return f'damping="{damping}" armature="{armature}" frictionloss="{friction}"'


@st.composite
def _transmissions(draw, floating: bool) -> list[str]:
    """Actuators whose moment MuJoCo computes, each present a third of the time: a motor's wrench at the tip, a
    servo on the tip's offset along one axis of the reference site, and on a floating base a force and torque on
    its free joint."""
    out = []
    if draw(st.integers(0, 2)) == 0:
        gear = [draw(st.floats(-1, 1)) for _ in range(3)] + [draw(st.floats(-0.05, 0.05)) for _ in range(3)]
        out.append(f'<motor site="tip" gear="{" ".join(_f(g) for g in gear)}" ctrlrange="-1 1"/>')
    if draw(st.integers(0, 2)) == 0:
        kp, axis = draw(st.floats(1.0, 50.0)), draw(st.sampled_from(["1 0 0", "0 1 0", "0 0 1"]))
        out.append(
            f'<position site="tip" refsite="reference" gear="{axis} 0 0 0" kp="{_f(kp)}" '
            f'kv="{_f(draw(st.floats(0, 0.1)) * kp)}" ctrlrange="-.2 .2"/>'
        )
    if floating and draw(st.integers(0, 2)) == 0:
        out.append(f'<motor joint="base" gear="0 0 {_f(draw(st.floats(1, 20)))} 0 0 .1" ctrlrange="-1 1"/>')
    return out


def _muscle(first: tuple, actuated: set[str]) -> list[str]:
    """A muscle on the first link's hinge where nothing else drives it and its range is closed, its length range
    that range widened by 1 rad each side (a start past an end stays on the muscle's curves). It takes no draw of its
    own, so that the documents drawn stay those drawn before muscles were."""
    _, joint, low, high, slide = first
    if slide or joint in actuated or not (np.isfinite(low) and np.isfinite(high)):
        return []
    return [f'<muscle joint="{joint}" force="1" lengthrange="{_f(low - 1.0)} {_f(high + 1.0)}"/>']


@st.composite
def robot_classes(draw) -> RawDocument:
    """An arm of 2-5 links (hinges, some slides) with the classes above, a keyframe that starts 1-3 joints past
    their ends, position servos and motors, and optionally a two-finger gripper coupled by a joint equality."""
    count = draw(st.integers(2, 5))
    links = [draw(_link(i)) for i in range(count)]
    body = "".join(opening for opening, *_ in links)
    if draw(st.booleans()):  # a welded sensor frame with mass and no inertia
        body += '<body name="sensor" pos=".05 0 0"><inertial pos="0 0 0" mass=".05" diaginertia="0 0 0"/></body>'
    gripper = draw(st.booleans())
    if gripper:
        body += (
            '<body name="palm" pos=".05 0 0"><inertial pos="0 0 0" mass=".1" diaginertia="1e-4 1e-4 1e-4"/>'
            '<body name="left"><joint name="left" type="slide" axis="0 1 0" range="0 .04" damping=".1"/>'
            '<geom type="box" size=".01 .01 .03" pos="0 .02 0" mass=".02"/></body>'
            '<body name="right"><joint name="right" type="slide" axis="0 -1 0" range="0 .04" damping=".1"/>'
            '<geom type="box" size=".01 .01 .03" pos="0 -.02 0" mass=".02"/></body></body>'
        )
    body += '<site name="tip" pos=".1 0 0"/>' + "</body>" * count
    floating = draw(st.booleans())  # the arm on a floating base, its free joint damped
    if floating:
        body = (
            f'<body name="base" pos="0 0 1"><joint name="base" type="free" {_free_joint(draw, frictional=True)}/>'
            f'<inertial pos="0 0 0" mass="2" diaginertia=".02 .03 .04"/>{body}</body>'
        )
    tossed = draw(st.booleans())  # a free object thrown spinning, its centre of mass off its origin
    if tossed:
        size = " ".join(_f(draw(st.floats(0.01, 0.05))) for _ in range(3))
        body += (
            f'<body name="object" pos="1 0 1"><joint name="object" type="free" {_free_joint(draw)}/>'
            f'<geom type="ellipsoid" size="{size}" pos="{_f(draw(st.floats(0, 0.02)))} 0 0" '
            f'mass="{_f(draw(st.floats(0.02, 0.5)))}"/></body>'
        )
    qpos = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0] if floating else []
    past = draw(st.lists(st.integers(0, count - 1), min_size=1, max_size=min(3, count), unique=True))
    for i, (_, _, lo, hi, slide) in enumerate(links):
        beyond = draw(st.floats(0.02, 0.1 if slide else 0.5))
        high = draw(st.booleans())
        closed = np.isfinite(hi if high else lo)  # past a closed end only
        qpos.append((hi + beyond if high else lo - beyond) if i in past and closed else 0.0)
    actuators, driven = [], set()  # the servos' and motors' joints
    for i, (_, name, lo, hi, _) in enumerate(links):
        driven.add(name)
        if draw(st.booleans()):
            kp = draw(st.floats(5.0, 200.0))
            span = (lo if np.isfinite(lo) else -3.0, hi if np.isfinite(hi) else 3.0)  # servo targets: a closed span
            actuators.append(
                f'<position joint="{name}" kp="{_f(kp)}" kv="{_f(draw(st.floats(0, 0.1)) * kp)}" '
                f'ctrlrange="{_f(span[0])} {_f(span[1])}"/>'
            )
        elif draw(st.booleans()):
            actuators.append(f'<motor joint="{name}" gear="{_f(draw(st.floats(1, 50)))}" ctrlrange="-1 1"/>')
        else:
            driven.discard(name)
    actuators += draw(_transmissions(floating))
    equality = ""
    if gripper:
        qpos += [0.02, 0.02]
        actuators.append('<position joint="left" kp="50" kv="2" ctrlrange="0 .04"/>')
        if draw(st.booleans()):
            actuators.append('<position joint="right" kp="50" kv="2" ctrlrange="0 .04"/>')
        equality = '<equality><joint joint1="left" joint2="right"/></equality>'
    qvel = [0.0] * ((6 if floating else 0) + count + (2 if gripper else 0))
    if tossed:
        qpos += [1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]
        qvel += [draw(st.floats(-1, 1)) for _ in range(3)] + [draw(st.floats(-5, 5)) for _ in range(3)]
    solver = ' iterations="1" ls_iterations="5"' if draw(st.integers(0, 3)) == 0 else ""  # Playground's setting
    actuators += _muscle(links[0], driven)
    ctrl = f' ctrl="{" ".join("0" for _ in actuators)}"' if actuators else ""
    key = (
        f'<keyframe><key qpos="{" ".join(_f(q) for q in qpos)}" qvel="{" ".join(_f(float(v)) for v in qvel)}"{ctrl}/>'
        "</keyframe>"
    )
    xml = (
        f'<mujoco model="robot_class"><compiler angle="radian"/><option timestep="0.002"{solver}/>'
        f'<worldbody><site name="reference" pos="0 .1 .8"/>{body}</worldbody>'
        f"<actuator>{''.join(actuators)}</actuator>{equality}{key}</mujoco>"
    )
    return RawDocument(xml, label="robot class")
