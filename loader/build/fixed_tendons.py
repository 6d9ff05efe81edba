"""Fixed tendons: linear combinations of joint positions. MuJoCo's passive `<tendon><fixed>` springs and dampers
are applied as MuJoCo applies them (`PassiveTendon`, exact); the linear part of joint and tendon equalities becomes
a PhysX fixed tendon (`create_fixed_tendon`, `equality.py`).

A PhysX fixed tendon is a tree of links whose incoming joints carry coefficients; its length is
sum(coefficient * q) and its spring force reaches each joint scaled by the joint's `recip_coefficient`. Setting
that to the coefficient itself gives MuJoCo's J^T f (measured: two equal links coupled q_a - 0.5 q_b = 0.3 settle
at 0.24 and -0.12, as J^T f predicts).
PhysX divides a tendon's stiffness and damping among the tendon's joints (every link below its root, those with
coefficient 0 included): measured on 1-4 sibling hinges, the force is 1/n of the stated gains. Times n, one step
is implicit, f = -K (L + dt J v') - D J v' (J v' the rate after the step),
to 1e-8 on two hinges with coefficients (1, -1), (1, 0.5), (-0.5, 1), (2, 3) at small gains. PhysX solves the
tendon iteratively: with mixed-sign coefficients and strong gains (dt D J M^-1 J^T of 3 to 6) it needs about 50
position iterations to reach 1e-5, and with coefficients (1, -2) at 12 it diverges.
MuJoCo (implicit and implicitfast) treats a tendon's damping implicitly only through its diagonal D J_i^2 in the
joint-space step (measured to 1e-16 on three hinges), where a PhysX tendon is implicit in the whole D J J^T and in
its spring: 2.3e-3 rad over 1 s on a three-hinge fixture, 4.2e-7 with `PassiveTendon`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import sapien

from .. import mj


def fixed_tendon_terms(model: mujoco.MjModel, tendon: int) -> list[tuple[int, float]]:
    """(MuJoCo joint id, coefficient) pairs of a fixed tendon, or [] for a spatial one."""
    start, count = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    if any(int(model.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT) for w in range(start, start + count)):
        return []
    return [(int(model.wrap_objid[w]), float(model.wrap_prm[w])) for w in range(start, start + count)]


def create_fixed_tendon(
    articulation: sapien.physx.PhysxArticulation, dof_coefficients: dict[int, float], rest_length: float,
    stiffness: float, damping: float,
) -> None:
    """A PhysX fixed tendon over the DoFs (indices into `articulation.active_joints`) with these coefficients and
    PhysX's stated gains, which PhysX divides among the tendon's joints (module notes)."""
    joints = articulation.active_joints
    coefficient_of = {joints[d].child_link.name: c for d, c in dof_coefficients.items()}
    # the tendon's links: every link from the common ancestor down to each coupled joint's child link
    paths = []
    for d in dof_coefficients:
        path, link = [], joints[d].child_link
        while link is not None:
            path.append(link)
            link = link.parent
        paths.append(path[::-1])
    common = 0
    while all(len(p) > common + 1 for p in paths) and len({p[common + 1].name for p in paths}) == 1:
        common += 1
    while paths[0][common].name in coefficient_of:  # the tendon's root joint carries no coefficient
        common -= 1
    chain, seen = [paths[0][common]], {paths[0][common].name}
    for path in paths:
        for link in path[common + 1 :]:
            if link.name not in seen:
                chain.append(link)
                seen.add(link.name)
    coefficients = [coefficient_of.get(link.name, 0.0) if i else 0.0 for i, link in enumerate(chain)]
    articulation.create_fixed_tendon(
        chain, coefficients, coefficients, rest_length=rest_length, offset=0.0, stiffness=stiffness, damping=damping,
    )
