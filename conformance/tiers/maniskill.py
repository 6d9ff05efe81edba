"""Tier `maniskill` (opt-in: `--tiers maniskill`): the model as a ManiSkill robot (`loader.maniskill.register_agent`)
in `Empty-v1` (physx_cpu, no rendering, state observations, ManiSkill's default scene configuration but MuJoCo's
gravity: its TGS solver), driven under `mujoco_ctrl` through ManiSkill's own `env.step` with the `actuated` tier's ctrl
sequence and judged as that tier judges (fixed-base tolerances from `[tolerance.maniskill]`), so that what holds for the
loader is shown to hold inside ManiSkill as its users run it. ManiSkill's action is float32: the ctrl it applies is
MuJoCo's rounded to it.

Skipped, with the reason: without mani_skill (the `maniskill` extra); when the model's timestep is not 1/n s for an
integer n (ManiSkill sets the simulation frequency); when the model is not one kinematic tree (ManiSkill's loader
builds one robot); and wherever `actuated` skips.

Tier `maniskill_tensor` (opt-in: `--tiers maniskill_tensor`) judges `mujoco_ctrl_tensor`, the joint actuation law on
ManiSkill's tensors that its GPU backend runs, the same way on the CPU backend, under ManiSkill's default TGS and
`[tolerance.maniskill]`. What the law does not carry and the harness can take out of both sides (equalities other
than joint couplings, fluid: conformance/gaps.py) is taken out of MuJoCo's model and the robot's
alike, and named in the notes, so that the tier judges the law itself; what else the law leaves out
(`JointActuation.not_carried`: a floating root, ...) stays in and is named too. Skipped, with the reason, where the
robot is outside the law, and wherever `maniskill` skips.
"""

from __future__ import annotations

import dataclasses
import hashlib
import warnings

import mujoco
import numpy as np

from loader.plan.physx_settings import matched_config

from ..gaps import GAPS, without
from ..report import TierReport, skipped
from ..tolerances import Tolerances
from .actuated import actuated, unmapped_reason

TIER = "maniskill"
TENSOR_TIER = "maniskill_tensor"
# what `mujoco_ctrl_tensor` does not carry that the harness takes out of both sides (conformance/gaps.py)
TENSOR_GAPS = ("uncoupled_equality", "fluid")
TGS_TOLERANCES = ("one_step_qvel_fixed", "rollout_qpos_fixed")  # `[tolerance.maniskill]` replaces actuated's


class _Scene:
    """The sub-scene, whose `step()` is one ManiSkill `env.step` (one physics step) under the recorded ctrl."""

    def __init__(self, sub_scene, env, driven):
        self.sub_scene, self.env, self.driven = sub_scene, env, driven

    def step(self) -> None:
        self.env.step(np.asarray(self.driven.pending, np.float32))

    def __getattr__(self, name):
        return getattr(self.sub_scene, name)


class ThroughEnv:
    """The agent's `LoadResult`, stepped by ManiSkill: an advancing `set_ctrl` only records the ctrl, which the next
    `scene.step()` hands to `env.step` as the action (`mujoco_ctrl` applies it before the physics step); everything
    else is the result's."""

    def __init__(self, result, env):
        self.result = result
        self.pending = np.zeros(result.model.nu)
        self.scene = _Scene(result.scene, env, self)

    def set_ctrl(self, ctrl, qfrc_applied=None, advance: bool = True) -> None:
        if advance and qfrc_applied is None:
            self.pending = np.zeros(self.result.model.nu) if ctrl is None else np.array(ctrl, dtype=np.float64)
            return
        self.result.set_ctrl(ctrl, qfrc_applied, advance)

    def __getattr__(self, name):
        return getattr(self.result, name)


class ThroughTensorEnv(ThroughEnv):
    """`ThroughEnv` under `mujoco_ctrl_tensor`, whose controller (`law`) keeps its own activations and last step:
    a state set from outside sets its activations too and leaves no step to settle, a state read settles the last
    one, and the drives stay the law's whenever the result's own `set_ctrl` wrote them (`disable_actuators`)."""

    def __init__(self, result, env):
        super().__init__(result, env)
        self.law = env.unwrapped.agent.controller.controllers["ctrl"]

    def set_state(self, qpos, qvel=None) -> None:
        self.result.set_state(qpos, qvel)
        self.law.rows = None  # no step of the law's to settle

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The state after the last physics step, its floating root settled as the law's next step would."""
        self.law.settle()
        return self.result.get_state()

    def set_act(self, act) -> None:
        """MuJoCo's act (na) into the law's activations (one env x nu: an actuator's column is its act)."""
        self.result.set_act(act)
        model = self.result.model
        columns = np.zeros(model.nu)
        if act is not None:
            has = model.actuator_actadr >= 0
            columns[has] = np.asarray(act, np.float64)[model.actuator_actadr[has]]
        self.law.act = self.law.act.new_tensor(columns)[None]

    def disable_actuators(self, disabled: bool = True) -> None:
        self.result.disable_actuators(disabled)
        self.law.set_drive_property()


def empty_env(
    uid: str,
    mode: str,
    sim_freq: int,
    control_freq: int,
    scene_config: dict | None = None,
    backend: str = "physx_cpu",
    num_envs: int = 1,
):
    """ManiSkill's `Empty-v1` with the registered agent `uid` under `mode`, on `backend` (the CPU's, or `physx_cuda`
    with `num_envs` sub-scenes) without rendering (`scene_config`: PhysX settings over ManiSkill's default, TGS)."""
    import gymnasium as gym
    import mani_skill.envs  # noqa: F401  registers Empty-v1

    sim_config = {"sim_freq": sim_freq, "control_freq": control_freq}
    if scene_config is not None:
        sim_config["scene_config"] = scene_config
    return gym.make(
        "Empty-v1",
        robot_uids=uid,
        num_envs=num_envs,
        sim_backend=backend,
        render_backend="none",
        obs_mode="state",
        control_mode=mode,
        sim_config=sim_config,
    )


def _env_skip(result, model: mujoco.MjModel, tier: str, tolerances: Tolerances) -> TierReport | None:
    """Why the model cannot be judged through ManiSkill's env (without mani_skill, for one), or None."""
    try:
        import mani_skill.envs  # noqa: F401  registers Empty-v1
    except ImportError as exc:
        return skipped(tier, f"mani_skill is not installed (the maniskill extra): {exc}")
    sim_freq = _frequency(model)
    if np.float32(1.0 / sim_freq) != np.float32(model.opt.timestep):
        return skipped(tier, f"the timestep {model.opt.timestep:g} s is not 1/n s: ManiSkill sets a frequency")
    if len(result.articulations) != 1:
        return skipped(tier, f"{len(result.articulations)} kinematic trees: ManiSkill's loader builds one robot")
    return unmapped_reason(result, model, tier, tolerances)  # where `actuated` skips, before any env is made


def _frequency(model: mujoco.MjModel) -> int:
    return round(1.0 / model.opt.timestep)


def _uid(tier: str, path) -> str:
    return f"conformance-{tier}-" + hashlib.sha256(str(path).encode()).hexdigest()[:12]


def _under_tgs(tolerances: Tolerances) -> Tolerances:
    """actuated's tolerances with `[tolerance.maniskill]`'s fixed-base ones: ManiSkill's default solver, TGS."""
    return tolerances.with_overrides(
        {f"actuated.{name}": tolerances[f"maniskill.{name}"] for name in TGS_TOLERANCES},
        why="ManiSkill's default solver (TGS): tolerances.toml [tolerance.maniskill]",
    )


def maniskill(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    skip = _env_skip(result, model, TIER, tolerances)
    if skip is not None:
        return skip
    from loader.maniskill import register_agent

    uid, sim_freq = _uid(TIER, result.path), _frequency(model)
    scene_config = {"gravity": np.asarray(matched_config(model).gravity).tolist()}  # ManiSkill's solver: TGS
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loader's notes were counted by the session's load
        register_agent(result.path, uid, override=True)
        env = empty_env(uid, "mujoco_ctrl", sim_freq, sim_freq, scene_config)
    try:
        env.reset(seed=seed)
        (agent_result,) = env.unwrapped.agent.results
        report = actuated(ThroughEnv(agent_result, env), model, seed, _under_tgs(tolerances))
    finally:
        env.close()
    notes = [*report.notes, f"driven through ManiSkill's env.step (Empty-v1, mujoco_ctrl, {sim_freq} Hz)"]
    return dataclasses.replace(report, tier=TIER, notes=notes)


def maniskill_tensor(result, model: mujoco.MjModel, seed: int, tolerances: Tolerances) -> TierReport:
    skip = _env_skip(result, model, TENSOR_TIER, tolerances)
    if skip is not None:
        return skip
    from loader.maniskill import register_agent

    gaps = tuple(name for name in TENSOR_GAPS if GAPS[name].present(model))
    uid, sim_freq = _uid(TENSOR_TIER, result.path), _frequency(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spec = without(result.spec, gaps)  # the robot's and, compiled, MuJoCo's side: the same gaps out of both
        agent = register_agent(spec, uid, override=True)
    law = agent.joint_actuation
    if isinstance(law, str):
        return skipped(TENSOR_TIER, f"outside mujoco_ctrl_tensor's law: {law}")
    scene_config = {"gravity": np.asarray(matched_config(model).gravity).tolist()}  # ManiSkill's solver: TGS
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = empty_env(uid, "mujoco_ctrl_tensor", sim_freq, sim_freq, scene_config)
    try:
        env.reset(seed=seed)
        (agent_result,) = env.unwrapped.agent.results
        report = actuated(ThroughTensorEnv(agent_result, env), spec.compile(), seed, _under_tgs(tolerances))
    finally:
        env.close()
    taken = [f"taken out of both sides, which the law does not carry: {GAPS[name].what}" for name in gaps]
    taken += [f"left in, which the law does not carry: {what}" for what in law.not_carried]
    notes = [
        *report.notes,
        *taken,
        f"driven through ManiSkill's env.step (Empty-v1, mujoco_ctrl_tensor, {sim_freq} Hz)",
    ]
    return dataclasses.replace(report, tier=TENSOR_TIER, notes=notes)
