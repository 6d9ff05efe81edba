"""`python -m conformance maniskill-bench` (`pipx run nox -s maniskill -- bench`): ManiSkill's `Empty-v1` with a
robot registered by this loader, physics steps per second under `mujoco_ctrl` (MuJoCo's ctrl before every physics
step) against `pd_joint_pos` (PhysX's drives alone), each mode under the same seeded random walk of its actions
from the middle of its action space; and `mujoco_ctrl_tensor` where the robot is offered it (`tensor_ratio`: a law
meant for the GPU, timed on the CPU backend), with the PD and tensor modes on `physx_cuda` too where a CUDA device
is there (`gpu`, summed over `GPU_ENVS` sub-scenes; otherwise why not). The environments live in one process and
take turns, a round of control steps each (`ROUNDS`), and each mode's figure is its fastest round: a machine whose
speed drifts within the minute (a shared core) then slows every mode alike instead of whichever ran last. The ratio
is what a ManiSkill user pays for MuJoCo's behaviour on the CPU backend. Needs the `maniskill` extra; times are
compared only as ratios within one run."""

from __future__ import annotations

import time
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from . import corpus
from .summary import atomic_write_json
from .versions import versions

ROBOTS = {"panda": "franka_emika_panda/panda.xml", "leap_hand": "leap_hand/right_hand.xml"}
MODES = ("mujoco_ctrl", "pd_joint_pos")
TENSOR = "mujoco_ctrl_tensor"  # timed too where the robot is offered it (`tensor_ratio`), under the same walk
SUBSTEPS = 10  # physics steps per control step (ManiSkill's sim_freq / control_freq)
WALK = 0.01  # of each action's range per control step
WARMUP = 5  # control steps before the clock starts
ROUNDS = 10  # turns each mode takes (the figure is its fastest)
GPU_ENVS = 1024  # sub-scenes on physx_cuda, where a CUDA device is there
GPU_MODES = ("pd_joint_pos", "mujoco_ctrl_tensor")  # what runs per step on the device, under ManiSkill's TGS


class Walk:
    """One mode's environment and its random walk of actions."""

    def __init__(self, uid: str, mode: str, sim_freq: int, seed: int = 0):
        from .tiers.maniskill import empty_env

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the loader's notes were warned at the agent's registration
            self.env = empty_env(uid, mode, sim_freq, sim_freq // SUBSTEPS)
        self.env.reset(seed=seed)
        space = self.env.action_space
        low, high = np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)
        self.low, self.high = np.where(np.isfinite(low), low, -1.0), np.where(np.isfinite(high), high, 1.0)
        self.rng, self.action = np.random.default_rng(seed), (self.low + self.high) / 2

    def seconds(self, control_steps: int) -> float:
        """Seconds spent in `env.step` over `control_steps` steps of the walk."""
        low, high, elapsed = self.low, self.high, 0.0
        for _ in range(control_steps):
            self.action = np.clip(self.action + WALK * self.rng.standard_normal(low.size) * (high - low), low, high)
            start = time.perf_counter()
            self.env.step(self.action.astype(np.float32))
            elapsed += time.perf_counter() - start
        return elapsed


def law_operations(env) -> int:
    """The torch operations one `mujoco_ctrl_tensor` step dispatches before a physics step (the env's controller's
    `before_simulation_step`), counted as dispatched. On the GPU each is a kernel launch whatever the number of
    sub-scenes: the law's fixed cost per physics step there, before CUDA graphs. On the CPU backend, where this counts
    them, the row solve stops once its zones settle; on the device it runs all `ROW_PASSES`."""
    import torch
    from torch.utils._python_dispatch import TorchDispatchMode

    class Counted(TorchDispatchMode):
        def __init__(self):
            super().__init__()
            self.count = 0

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            self.count += 1
            return func(*args, **(kwargs or {}))

    agent = env.unwrapped.agent
    controller = getattr(agent.controller, "controllers", {}).get("ctrl", agent.controller)
    with torch.inference_mode(), Counted() as counted:
        controller.before_simulation_step()
    return counted.count


def steps_per_second(
    uid: str, sim_freq: int, control_steps: int, seed: int = 0, modes: tuple[str, ...] = MODES
) -> dict[str, float]:
    """Physics steps per second of `Empty-v1` with the agent `uid` under each of `modes`: `ROUNDS` turns of
    `control_steps / ROUNDS` env steps each (at least one), after `WARMUP`; each mode's fastest round; and, where
    `mujoco_ctrl_tensor` is among them, the operations its law dispatches per physics step (`law_operations`)."""
    walks = {mode: Walk(uid, mode, sim_freq, seed) for mode in modes}
    try:
        for walk in walks.values():
            walk.seconds(WARMUP)
        per_round = max(1, control_steps // ROUNDS)
        best = dict.fromkeys(modes, np.inf)
        for _ in range(ROUNDS):
            for mode, walk in walks.items():
                best[mode] = min(best[mode], walk.seconds(per_round))
        operations = {"tensor_ops": law_operations(walks[TENSOR].env)} if TENSOR in walks else {}
    finally:
        for walk in walks.values():
            walk.env.close()
    return {**{mode: per_round * SUBSTEPS / seconds for mode, seconds in best.items()}, **operations}


def gpu_steps_per_second(uid: str, sim_freq: int, control_steps: int, num_envs: int = GPU_ENVS) -> dict:
    """Physics steps per second summed over `num_envs` sub-scenes of `Empty-v1` on `physx_cuda` (ManiSkill's default
    scene configuration, TGS) under each of `GPU_MODES`, the actions a seeded random walk on the device, after
    `WARMUP` control steps; or why not measured. Written against ManiSkill's GPU API and not yet run on a GPU."""
    import torch

    if not torch.cuda.is_available():
        return {"skipped": "no CUDA device: physx_cuda needs one"}
    from .tiers.maniskill import empty_env

    row: dict = {"num_envs": num_envs}
    for mode in GPU_MODES:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = empty_env(uid, mode, sim_freq, sim_freq // SUBSTEPS, backend="physx_cuda", num_envs=num_envs)
        try:
            row[mode] = _gpu_walk(env, control_steps) * num_envs
        finally:
            env.close()
    row["tensor_ratio"] = row["mujoco_ctrl_tensor"] / row["pd_joint_pos"]
    return row


def _gpu_walk(env, control_steps: int, seed: int = 0) -> float:
    """One sub-scene's physics steps per second under a random walk of the actions from the middle of the space."""
    import torch

    env.reset(seed=seed)
    space, device = env.unwrapped.single_action_space, env.unwrapped.device
    low, high = (
        torch.as_tensor(np.where(np.isfinite(b), b, s), device=device)
        for b, s in ((space.low, -1.0), (space.high, 1.0))
    )
    generator = torch.Generator(device=device).manual_seed(seed)
    action = ((low + high) / 2).expand(env.unwrapped.num_envs, -1).clone()

    def walk(steps: int) -> None:
        nonlocal action
        for _ in range(steps):
            noise = torch.randn(action.shape, generator=generator, device=device)
            action = torch.clamp(action + WALK * noise * (high - low), low, high)
            env.step(action)
        torch.cuda.synchronize()

    walk(WARMUP)
    start = time.perf_counter()
    walk(control_steps)
    return control_steps * SUBSTEPS / (time.perf_counter() - start)


def maniskill_bench(out: Path, control_steps: int = 100) -> dict:
    """Each robot of `ROBOTS` found in the Menagerie slice under both modes; the JSON document written atomically."""
    import mujoco

    from loader.maniskill import register_agent

    robots = {}
    for name, source in ROBOTS.items():
        root, origin = corpus.menagerie_root()
        path = root / source if root is not None else None
        if path is None or not path.is_file():
            robots[name] = {"skipped": f"{source} not found ({origin})"}
            continue
        sim_freq = round(1.0 / float(mujoco.MjModel.from_xml_path(str(path)).opt.timestep))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            agent = register_agent(path, f"bench_{name}", override=True)
        tensor = not isinstance(agent.joint_actuation, str)  # the robot is offered `mujoco_ctrl_tensor`
        row = steps_per_second(agent.uid, sim_freq, control_steps, modes=MODES + (TENSOR,) * tensor)
        row["sim_freq"], row["ratio"] = sim_freq, row["mujoco_ctrl"] / row["pd_joint_pos"]
        if tensor:
            row["tensor_ratio"] = row[TENSOR] / row["pd_joint_pos"]
        row["gpu"] = (
            gpu_steps_per_second(agent.uid, sim_freq, control_steps) if tensor else {"skipped": agent.joint_actuation}
        )
        robots[name] = row
    doc = {
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": versions(("mani-skill", "torch")),
        "control_steps": control_steps,
        "rounds": ROUNDS,
        "substeps": SUBSTEPS,
        "robots": robots,
    }
    atomic_write_json(Path(out), doc)
    return doc
