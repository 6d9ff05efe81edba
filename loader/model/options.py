"""MuJoCo's options as the per-step terms read them: one frozen snapshot taken when the terms are planned, so that
every term sees the same integrator, flags and timestep, and an edit of the model after load reaches none of them
until `LoadResult.replan()` (tests/test_loader_structure.py::test_model_edits_reach_the_steps_only_through_replan).
Also the PhysX setting the rows read beside the one the scene is given."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

from . import mj

IMPLICIT = (int(mujoco.mjtIntegrator.mjINT_IMPLICIT), int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST))
MAX_DEPENETRATION_VELOCITY = 0.1  # m/s; see docs/mapping.md#physx-settings and
# tests/test_loader_contact.py::test_arms_started_inside_each_other_come_apart_as_slowly_as_in_mujoco
CLAMPCTRL = int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)


@dataclass(frozen=True)
class Options:
    """`timestep`: the scene's, one PhysX step (the model's unless the scene was given another); `integrator`:
    MuJoCo's; `disableflags`: MuJoCo's `<flag ... ="disable">` bits; `tgs`: the scene's PhysX solver is TGS, whose
    drives do not step as MuJoCo's (`runtime/drive_forces.py`)."""

    timestep: float
    integrator: int
    disableflags: int
    explicit_damping: bool  # MuJoCo takes joint damping explicitly (`mj.explicit_damping`)
    tgs: bool = False

    @classmethod
    def of(cls, model: mujoco.MjModel, timestep: float | None = None, tgs: bool = False) -> Options:
        step = float(model.opt.timestep if timestep is None else timestep)
        return cls(step, int(model.opt.integrator), int(model.opt.disableflags), mj.explicit_damping(model), tgs)

    @property
    def implicit(self) -> bool:
        """implicit or implicitfast: MuJoCo treats damping (and actuator kv) implicitly."""
        return self.integrator in IMPLICIT

    @property
    def clamps_ctrl(self) -> bool:
        return not self.disableflags & CLAMPCTRL
