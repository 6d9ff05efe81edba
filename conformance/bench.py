"""`nox -s bench`: per model, the loader's time against MuJoCo's own compile of the same file, the harness's
simulated steps per second (SAPIEN and MuJoCo rollouts with the harness's state read-back), and the cost of the
loader's per-step `set_ctrl` against PhysX's own step."""

from __future__ import annotations

import time
import warnings
from datetime import datetime, timezone
from pathlib import Path

import mujoco
import numpy as np

from . import corpus, reference
from .manifest import ModelEntry
from .summary import atomic_write_json
from .versions import versions

REPEATS = 3  # best of: the first compile of a file also pays for reading meshes from disk


def _best(fn, repeats: int = REPEATS) -> tuple[float, object]:
    best, value = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - t0)
    return best, value


def bench_model(path: str, steps: int) -> dict:
    from .session import open_session
    from .tiers.rollouts import disable_contacts, sapien_rollout

    compile_s, _ = _best(lambda: mujoco.MjModel.from_xml_path(path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sessions = [open_session(path) for _ in range(REPEATS)]
    load_s = min(s.load_seconds for s in sessions)  # the loader's own time (its compile included)
    session = sessions[-1]
    model, result = session.model, session.result
    ref, _ = reference.matched(model, contact=False)
    disable_contacts(result)
    qpos0, qvel0, _ = reference.initial_state(model)
    command = np.zeros((steps, model.nv))
    t0 = time.perf_counter()
    reference.rollout(ref, qpos0, qvel0, steps, command)
    mujoco_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    sapien_rollout(result, model, qpos0, qvel0, command)
    sapien_s = time.perf_counter() - t0
    set_ctrl_s, step_s = _set_ctrl_cost(result, steps)
    return {
        "mujoco_compile_s": compile_s,
        "loader_load_s": load_s,
        "load_over_compile": load_s / compile_s if compile_s > 0 else None,
        "steps": steps,
        "harness_mujoco_steps_per_s": steps / mujoco_s,
        "harness_sapien_steps_per_s": steps / sapien_s,
        "set_ctrl_us": 1e6 * set_ctrl_s / steps,
        "physx_step_us": 1e6 * step_s / steps,
        "set_ctrl_over_step": set_ctrl_s / step_s if step_s > 0 else None,
        "nbody": model.nbody, "nv": model.nv, "ngeom": model.ngeom,
    }


def _set_ctrl_cost(result, steps: int) -> tuple[float, float]:
    """Seconds spent in `result.set_ctrl` (the loader's per-step work: clamps, tendons, friction drives) and in
    PhysX's step, over `steps` actuated steps at zero ctrl."""
    ctrl = np.zeros(result.model.nu)
    result.disable_actuators(False)
    set_ctrl_s = step_s = 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        result.set_ctrl(ctrl)
        t1 = time.perf_counter()
        result.scene.step()
        set_ctrl_s, step_s = set_ctrl_s + t1 - t0, step_s + time.perf_counter() - t1
    result.disable_actuators(True)
    return set_ctrl_s, step_s


def bench(entries: list[ModelEntry], out: Path, steps: int = 200) -> dict:
    """Benchmark every resolvable entry in this process and write the JSON document atomically."""
    models = {}
    for entry in entries:
        resolved = corpus.resolve(entry)
        if resolved.path is None:
            models[entry.id] = {"skipped": resolved.skip_reason}
            continue
        try:
            models[entry.id] = bench_model(str(resolved.path), steps)
        except Exception as exc:  # noqa: BLE001 - one broken model does not end the benchmark
            models[entry.id] = {"error": f"{type(exc).__name__}: {exc}"}
    doc = {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": versions(),
           "repeats": REPEATS, "models": models}
    atomic_write_json(Path(out), doc)
    return doc
