"""MuJoCo and SAPIEN stepped side by side: the loaded model (a `loader.LoadResult`) against MuJoCo's.

Every helper compares SAPIEN's state, read back in MuJoCo's layout, with MuJoCo's after the same step under the
same ctrl. MuJoCo is the oracle; quaternions are compared as numbers (the fixtures that use these have none, or
keep them near the identity)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from loader import DivergenceError, MJCFLoader

CtrlAt = Callable[[int, mujoco.MjData], "np.ndarray | None"]


def no_ctrl(step: int, data: mujoco.MjData) -> None:
    return None


@dataclass
class Paired:
    """Per step: the worst |SAPIEN - MuJoCo| position and velocity, and each side's fastest DoF (inf where
    SAPIEN's velocity is not finite; a run whose state `set_ctrl` refused ends with one such step)."""

    qpos: np.ndarray
    qvel: np.ndarray
    sapien_speed: np.ndarray
    mujoco_speed: np.ndarray


def solver_scene(model: mujoco.MjModel, tgs: bool):
    """A CPU scene matched to `model` (gravity, timestep) on PhysX's TGS solver (`tgs`) or PGS; PhysX's global
    configuration is left as it was."""
    import sapien

    previous = sapien.physx.get_scene_config()
    sapien.physx.set_scene_config(gravity=model.opt.gravity, enable_tgs=tgs)
    try:
        scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    finally:
        sapien.physx.set_scene_config(previous)
    scene.timestep = float(model.opt.timestep)
    return scene


def contact_free(path: str | Path, mutate: Callable | None = None):
    """Load `path` with contacts off on both sides and MuJoCo on implicitfast (the integrator the drive mapping
    assumes); `mutate(result)` edits the loaded result (a deliberate mistake). Returns (result, model)."""
    result = MJCFLoader().load(path)
    result.set_contacts(False)
    model = result.model
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    if mutate:
        mutate(result)
    return result, model


def at_keyframe(path: str | Path, key: int = 0, contacts: str = "mujoco"):
    """Load `path` with both sides at keyframe `key` (its velocities too), the model's own contacts `contacts`'s
    (`MJCFLoader.contacts`). Returns (result, model, data)."""
    loader = MJCFLoader()
    loader.contacts = contacts
    result = loader.load(path)
    model = result.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, key)
    result.set_state(data.qpos, data.qvel)
    return result, model, data


def paired_rollout(
    result, model: mujoco.MjModel, data: mujoco.MjData, steps: int, ctrl_at: CtrlAt = no_ctrl, set_ctrl: bool = True
) -> Paired:
    """Step MuJoCo (`model`, `data`) and SAPIEN together from their current states. `ctrl_at(step, data)` gives
    the step's ctrl (None: MuJoCo's `data.ctrl` as it is, on both sides); `set_ctrl=False` steps SAPIEN bare
    (after `release()`)."""
    qpos, qvel, sapien_speed, mujoco_speed = [], [], [], []
    for step in range(steps):
        ctrl = ctrl_at(step, data)
        if ctrl is not None:
            data.ctrl[:] = ctrl
        if set_ctrl:
            try:
                result.set_ctrl(data.ctrl.copy())
            except DivergenceError:  # SAPIEN's state is no longer finite: the paired run ends there
                qpos.append(np.inf), qvel.append(np.inf), sapien_speed.append(np.inf)
                mujoco_speed.append(np.abs(data.qvel).max(initial=0.0))
                break
        mujoco.mj_step(model, data)
        result.scene.step()
        q, v = result.get_state()
        qpos.append(np.abs(q - data.qpos).max(initial=0.0))
        qvel.append(np.abs(v - data.qvel).max(initial=0.0))
        sapien_speed.append(np.abs(v).max(initial=0.0) if np.isfinite(v).all() else np.inf)
        mujoco_speed.append(np.abs(data.qvel).max(initial=0.0))
    return Paired(*(np.array(x) for x in (qpos, qvel, sapien_speed, mujoco_speed)))


def replay(
    result, model: mujoco.MjModel, ctrl_at: CtrlAt, seconds: float, reference: mujoco.MjModel | None = None
) -> np.ndarray:
    """From the first keyframe (or qpos0) on both sides, `seconds` of the same ctrl sequence; the worst |qpos|
    difference per step. `reference` is the model MuJoCo runs (default: `model`)."""
    reference = reference or model
    data = mujoco.MjData(reference)
    key = 0 if reference.nkey else None
    if key is None:
        mujoco.mj_resetData(reference, data)
    else:
        mujoco.mj_resetDataKeyframe(reference, data, key)
    result.reset(key)
    return paired_rollout(result, reference, data, int(seconds / reference.opt.timestep), ctrl_at).qpos


def one_step(
    result, model: mujoco.MjModel, qpos, qvel, ctrl=None, data: mujoco.MjData | None = None, advance: bool = True
) -> np.ndarray:
    """Both sides put at (qpos, qvel) and stepped once under `ctrl`; |SAPIEN - MuJoCo| velocity per DoF. `data`:
    MuJoCo's data to step (its act and warm start kept; default a fresh one). `advance=False`: activations are not
    advanced (a probe step off the main run)."""
    data = mujoco.MjData(model) if data is None else data
    qpos, qvel = np.array(qpos, dtype=float), np.array(qvel, dtype=float)
    data.qpos[:], data.qvel[:] = qpos, qvel
    if ctrl is not None:
        data.ctrl[:] = ctrl
    result.mapping.set_state(result.articulations, qpos, qvel)
    result.set_ctrl(None if ctrl is None else np.array(ctrl, dtype=float), advance=advance)
    mujoco.mj_step(model, data)
    result.scene.step()
    return np.abs(result.get_state()[1] - data.qvel)
