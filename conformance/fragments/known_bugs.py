"""Open loader bugs, each reproduced by a file in `corpus/regressions/` (reason in `known_bugs.toml`).

While a bug is open, a generated document that can trigger it would fail the properties for a reason already
on record. Each entry says which documents can trigger it and which tiers it breaks; such a tier failure is
counted as "known bug <file>" (never silently passed). Delete the entry when the loader is fixed: the
regression's strict xfail turns into an XPASS error that day, as a reminder.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class KnownBug:
    regression: str  # file name in corpus/regressions/
    tiers: tuple[str, ...]
    triggers: Callable[[object, mujoco.MjModel], bool]  # (load result, compiled model)


ILL_CONDITIONED = 50.0  # condition number of MuJoCo's joint-space inertia at qpos0 beyond which one-step
# accelerations were seen 0.1-0.3 % off (fuzz finds at 128, 335 and 363; 70 agreed to 2e-6)


def _ill_conditioned(result, model: mujoco.MjModel) -> bool:
    if model.nv < 2:
        return False
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return bool(np.linalg.cond(full) > ILL_CONDITIONED)


# fixed in the loader: free_joint_class_damping_armature.xml (now listed as unsupported),
# zero_dof_tree_child_pose.xml (set_state updates joint-less trees) and velocity_actuator_unreached_forcerange.xml
# (the drive force limit is listed as an approximation), slide_*_metres_from_its_zero.xml (joint frames onto a
# coordinate axis are exact in float32 now, `loader/frames.py`); their files stay as regressions
KNOWN_BUGS: list[KnownBug] = [
    KnownBug("ill_conditioned_two_hinges.xml", ("dynamics", "actuated"), _ill_conditioned),
]


def known_bug(tier: str, result, model: mujoco.MjModel) -> str | None:
    """The regression file of an open bug that explains a failure of `tier` on this model, if any."""
    for bug in KNOWN_BUGS:
        if tier in bug.tiers and bug.triggers(result, model):
            return bug.regression
    return None
