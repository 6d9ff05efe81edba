"""What the planning half hands the runtime about each equality: an `EqualityLink` per MuJoCo equality, and for a
connect or weld built as a PhysX D6 joint the `D6Joint` record the runtime's soft law drives
(`runtime/equalities.py`). Derivation: docs/mapping.md#equalities."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sapien

from .soft_row import SoftRow


@dataclass(frozen=True)
class D6Joint:
    """A connect or weld as the PhysX D6 joint the load built: its drive and ends (`parent` None: the world or a
    static body at `parent_pose`), MuJoCo's anchor on each end in its body frame, the parent's D6 frame rotation
    (`frame`) and the child's (`child_rotation`), MuJoCo's soft row and diagApprox per row (3 for a connect, 6 for a
    weld), and for a weld its relpose rotation and torquescale."""

    drive: sapien.physx.PhysxDriveComponent
    child: sapien.physx.PhysxArticulationLinkComponent
    child_anchor: np.ndarray
    parent: sapien.physx.PhysxArticulationLinkComponent | None
    parent_anchor: np.ndarray
    parent_pose: sapien.Pose
    frame: sapien.Pose
    row: SoftRow
    diag_approx: np.ndarray
    equality: int  # MuJoCo's equality id
    child_body: int  # MuJoCo body ids of the ends
    parent_body: int
    articulation: int | None  # the child's articulation
    child_rotation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    weld: bool = False
    relative_quat: np.ndarray | None = None  # a weld's relpose rotation (body2 in body1's frame)
    torquescale: float = 0.0  # a weld's (0 for a connect: no rotational rows)
    child_is_body1: bool = False


@dataclass
class EqualityLink:
    """What an equality constraint became: MuJoCo's row (`kind` "MuJoCo row", applied by `runtime/rows.py`, with a
    D6 joint standing by for `release()` where it is a connect or weld), a D6 joint (`kind` "D6 joint"), or nothing
    (`mapped` False, with the `reason`)."""

    name: str
    kind: str
    mapped: bool
    reason: str = ""
    joint: D6Joint | None = None  # the D6 joint built for a connect or weld
    index: int = -1  # MuJoCo's equality id
