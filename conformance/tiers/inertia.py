"""Tier 3: per-body mass, centre of mass and full inertia tensor, compared in the world frame at qpos0."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import sapien_side
from ..data_pool import borrowed
from ..report import TierReport, judged, metric, skipped
from ..tolerances import Tolerances


def _rotation(q_wxyz: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q_wxyz, dtype=float))
    return mat.reshape(3, 3)


def link_inertia_world(link) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, world centre of mass, world inertia tensor about it) as PhysX holds them."""
    cmass = link.entity_pose * link.cmass_local_pose
    rot = _rotation(cmass.q)
    tensor = rot @ np.diag(np.asarray(link.inertia, dtype=float)) @ rot.T
    return float(link.mass), np.asarray(cmass.p, dtype=float), tensor


def inertia(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    """Relative mass error, COM distance, and the full tensor error relative to the body's largest moment, less
    an absolute floor (`inertia.tensor_floor`: what a zero or tiny moment may become in PhysX).

    Only bodies with mass in MuJoCo count; massless bodies (helper frames) carry whatever PhysX needs."""
    with borrowed(model) as data:
        mujoco.mj_kinematics(model, data)
        sapien_side.set_state(result, model.qpos0, np.zeros(model.nv))
        floor = tolerances["inertia.tensor_floor"]
        mass_err, com_err, tensor_err, tensor_floor, notes = [], [], [], [], []
        for b in range(1, model.nbody):
            link = sapien_side.body_link(result, b)
            if link is None or model.body_mass[b] <= 0:
                continue
            mass, com, tensor = link_inertia_world(link)
            ref_rot = data.ximat[b].reshape(3, 3)
            ref_tensor = ref_rot @ np.diag(model.body_inertia[b]) @ ref_rot.T
            scale = max(float(np.max(model.body_inertia[b])), floor)
            mass_err.append(abs(mass - model.body_mass[b]) / model.body_mass[b])
            com_err.append(np.linalg.norm(com - data.xipos[b]))
            tensor_err.append(np.max(np.abs(tensor - ref_tensor)) / scale)
            tensor_floor.append(floor / scale)
        if not mass_err:
            return skipped("inertia", "no body with mass is carried by an articulation link")
        return judged(
            "inertia",
            [
                metric("mass", mass_err, tolerances["inertia.mass"], "relative"),
                metric("com", com_err, tolerances["inertia.com"], "m"),
                metric(
                    "tensor", tensor_err, tolerances["inertia.tensor"], "relative to largest moment", floor=tensor_floor
                ),
            ],
            notes,
            settings={"bodies": len(mass_err)},
        )
