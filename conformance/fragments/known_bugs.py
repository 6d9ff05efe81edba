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


ILL_CONDITIONED = 100.0  # condition number of MuJoCo's joint-space inertia, the largest over qpos0 and SAMPLES
# configurations within about 0.3 of it, beyond which one-step accelerations were seen 1e-5..3e-3 of the step's
# velocity change off (fuzz finds at 122, 440, 1070 and 3500; 92 agreed to 2e-6): a heuristic for a class not isolated
SAMPLES = 32


def _ill_conditioned(result, model: mujoco.MjModel) -> bool:
    if model.nv < 2:
        return False
    data = mujoco.MjData(model)
    full = np.zeros((model.nv, model.nv))
    rng = np.random.default_rng(0)
    hinge_slide = [int(model.jnt_qposadr[j]) for j in range(model.njnt)
                   if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))]
    for sample in range(SAMPLES + 1):
        data.qpos[:] = model.qpos0
        if sample:
            data.qpos[hinge_slide] += rng.normal(size=len(hinge_slide)) * 0.3
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        if np.linalg.cond(full) > ILL_CONDITIONED:
            return True
    return False


# fixed in the loader: free_joint_class_damping_armature.xml (now listed as unsupported),
# zero_dof_tree_child_pose.xml (set_state updates joint-less trees) and velocity_actuator_unreached_forcerange.xml
# (the drive force limit is listed as an approximation); their files stay as regressions
# ill_conditioned_hinge_and_slide*.xml are further finds of the ill-conditioned class
KNOWN_BUGS: list[KnownBug] = [
    KnownBug("ill_conditioned_two_hinges.xml", ("dynamics", "actuated"), _ill_conditioned),
]


def known_bug(tier: str, result, model: mujoco.MjModel) -> str | None:
    """The regression file of an open bug that explains a failure of `tier` on this model, if any."""
    for bug in KNOWN_BUGS:
        if tier in bug.tiers and bug.triggers(result, model):
            return bug.regression
    return None
