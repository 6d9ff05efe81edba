"""A fixed tendon's joints and coefficients, as MuJoCo compiled them."""

from __future__ import annotations

import mujoco


def fixed_tendon_terms(model: mujoco.MjModel, tendon: int) -> list[tuple[int, float]]:
    """(MuJoCo joint id, coefficient) pairs of a fixed tendon, or [] for a spatial one."""
    start, count = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    if any(int(model.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT) for w in range(start, start + count)):
        return []
    return [(int(model.wrap_objid[w]), float(model.wrap_prm[w])) for w in range(start, start + count)]
