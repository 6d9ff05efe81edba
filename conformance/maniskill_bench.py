"""`python -m conformance maniskill-bench` (`pipx run nox -s maniskill -- bench`): ManiSkill's `Empty-v1` with a
robot registered by this loader, physics steps per second under `mujoco_ctrl` (every per-step term before every
physics step) against `pd_joint_pos` (PhysX's drives alone), in one process, each mode under the same seeded random
walk of its actions from the middle of its action space. The ratio is what a ManiSkill user pays for MuJoCo's
behaviour on the CPU backend. Needs the `maniskill` extra; times are compared only as ratios within one run."""

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
SUBSTEPS = 10  # physics steps per control step (ManiSkill's sim_freq / control_freq)
WALK = 0.01  # of each action's range per control step
WARMUP = 5  # control steps before the clock starts


def steps_per_second(uid: str, mode: str, sim_freq: int, control_steps: int, seed: int = 0) -> float:
    """Physics steps per second of `Empty-v1` with the agent `uid` under `mode` over `control_steps` env steps."""
    from .tiers.maniskill import empty_env

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loader's notes were warned at the agent's registration
        env = empty_env(uid, mode, sim_freq, sim_freq // SUBSTEPS)
    try:
        env.reset(seed=seed)
        space = env.action_space
        low, high = np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)
        low, high = np.where(np.isfinite(low), low, -1.0), np.where(np.isfinite(high), high, 1.0)
        rng, action = np.random.default_rng(seed), (low + high) / 2
        elapsed = 0.0
        for step in range(WARMUP + control_steps):
            action = np.clip(action + WALK * rng.standard_normal(action.size) * (high - low), low, high)
            start = time.perf_counter()
            env.step(action.astype(np.float32))
            if step >= WARMUP:
                elapsed += time.perf_counter() - start
    finally:
        env.close()
    return control_steps * SUBSTEPS / elapsed


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
            uid = register_agent(path, f"bench_{name}", override=True).uid
        row = {mode: steps_per_second(uid, mode, sim_freq, control_steps) for mode in MODES}
        row["sim_freq"], row["ratio"] = sim_freq, row["mujoco_ctrl"] / row["pd_joint_pos"]
        robots[name] = row
    doc = {
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": versions(("mani-skill", "torch")),
        "control_steps": control_steps,
        "substeps": SUBSTEPS,
        "robots": robots,
    }
    atomic_write_json(Path(out), doc)
    return doc
