"""PhysX fixed tendons for the linear part of joint and tendon equalities: each joint's `recip_coefficient` is
its coefficient (so the force reaches the joints as J^T f), and the gains are multiplied by the number of joints
PhysX divides them among. Derivation: docs/mapping.md#equalities.
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
