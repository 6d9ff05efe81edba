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

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)


@dataclass(frozen=True)
class KnownBug:
    regression: str  # file name in corpus/regressions/
    tiers: tuple[str, ...]
    triggers: Callable[[object, mujoco.MjModel], bool]  # (load result, compiled model)


def _free_joint_passive(result, model: mujoco.MjModel) -> bool:
    for j in np.flatnonzero(model.jnt_type == _FREE):
        dofs = slice(model.jnt_dofadr[j], model.jnt_dofadr[j] + 6)
        if model.dof_damping[dofs].any() or model.dof_armature[dofs].any() or model.jnt_stiffness[j]:
            return True
    return False


def _jointless_tree_with_children(result, model: mujoco.MjModel) -> bool:
    return any(art.dof == 0 and len(art.links) > 1 for art in result.articulations)


KNOWN_BUGS = [
    KnownBug("free_joint_class_damping_armature.xml", ("dynamics",), _free_joint_passive),
    KnownBug("zero_dof_tree_child_pose.xml", ("kinematics", "inertia", "collision"), _jointless_tree_with_children),
]


def known_bug(tier: str, result, model: mujoco.MjModel) -> str | None:
    """The regression file of an open bug that explains a failure of `tier` on this model, if any."""
    for bug in KNOWN_BUGS:
        if tier in bug.tiers and bug.triggers(result, model):
            return bug.regression
    return None
