"""`nox -s bench`: per model, the loader's time against MuJoCo's own compile of the same file, cold (each in a fresh
process: first reads of the files, MuJoCo's mesh cache empty, first calls into PhysX) and warm (again in this
process), each the median over repeats; the harness's simulated steps per second (SAPIEN and MuJoCo rollouts with
the harness's state read-back); and the cost of the loader's per-step `set_ctrl` against PhysX's own step. The
totals sum the models. Times are only compared as ratios within one run: other jobs share the machine."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
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

REPEATS = 5  # the median over this many loads and compiles, cold and warm
COPIES = (1, 4, 16)  # the batch sizes whose per-copy set_ctrl cost is measured (`batch_costs`)
TARGET = 1.2  # load over compile the loader aims at, cold and warm
# A model whose MuJoCo compile is this short is judged by the loader's time beyond the compile instead of the ratio:
# the loader's fixed work (a scene, a MuJoCo data, the once-per-load checks) dwarfs a compile of a few bodies.
TINY_COMPILE_S = 5e-3
TINY_BEYOND_S = 5e-3  # the loader's time beyond the compile a tiny model may take, cold and warm
PROJECT = Path(__file__).resolve().parents[1]

# One cold measurement: a fresh interpreter imports what it needs, then times only the load or the compile.
_COLD = """
import sys, time, warnings
warnings.simplefilter("ignore")
import mujoco
from conformance.session import quiet_load
import loader
path, what = sys.argv[1], sys.argv[2]
t0 = time.perf_counter()
quiet_load(path) if what == "load" else mujoco.MjModel.from_xml_path(path)
print("seconds", time.perf_counter() - t0)
"""


def _timed(fn) -> tuple[float, object]:
    t0 = time.perf_counter()
    value = fn()
    return time.perf_counter() - t0, value


def cold_seconds(path: str, what: str) -> float:
    """Seconds of one `what` ("load" or "compile") of `path` in a fresh process (its MuJoCo log in a scratch
    folder)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(PROJECT), os.environ.get("PYTHONPATH")) if p))
    with tempfile.TemporaryDirectory() as scratch:
        done = subprocess.run(
            [sys.executable, "-c", _COLD, path, what],
            check=False,
            cwd=scratch,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    lines = [line.split()[1] for line in done.stdout.splitlines() if line.startswith("seconds ")]
    if done.returncode or not lines:
        raise RuntimeError(f"cold {what} failed: {(done.stderr or done.stdout).strip()[-500:]}")
    return float(lines[-1])


def _ratio(load_s: float, compile_s: float) -> float | None:
    return load_s / compile_s if compile_s > 0 else None


def load_timings(path: str, repeats: int = REPEATS) -> tuple[dict, object]:
    """Cold and warm median compile and load seconds of `path`, compile and load alternating so that the machine's
    other work weighs on both alike; and the last warm load's result."""
    from .session import quiet_load

    cold_compile, cold_load = [], []
    for _ in range(repeats):
        cold_compile.append(cold_seconds(path, "compile"))
        cold_load.append(cold_seconds(path, "load"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mujoco.MjModel.from_xml_path(path)  # this process's first compile and load are cold: untimed
        quiet_load(path)
        warm_compile, warm_load, result = [], [], None
        for _ in range(repeats):
            warm_compile.append(_timed(lambda: mujoco.MjModel.from_xml_path(path))[0])
            result = None  # the previous scene goes before the next is built
            seconds, result = _timed(lambda: quiet_load(path))
            warm_load.append(seconds)
    row = {
        "mujoco_compile_s": statistics.median(warm_compile),
        "loader_load_s": statistics.median(warm_load),
        "cold_mujoco_compile_s": statistics.median(cold_compile),
        "cold_loader_load_s": statistics.median(cold_load),
    }
    for when in ("", "cold_"):
        row[f"{when}load_over_compile"] = _ratio(row[f"{when}loader_load_s"], row[f"{when}mujoco_compile_s"])
        row[f"{when}beyond_compile_s"] = row[f"{when}loader_load_s"] - row[f"{when}mujoco_compile_s"]
    return row, result


def over_target(row: dict, when: str) -> bool:
    """Whether a model's load misses its target (`when`: "" warm, "cold_"): a tiny model's (`TINY_COMPILE_S`) by its
    time beyond the compile, every other's by load over compile."""
    if "loader_load_s" not in row:
        return False
    if row[f"{when}mujoco_compile_s"] < TINY_COMPILE_S:
        return row[f"{when}beyond_compile_s"] > TINY_BEYOND_S
    return (row[f"{when}load_over_compile"] or 0) > TARGET


def bench_model(path: str, steps: int, repeats: int = REPEATS) -> dict:
    from .tiers.rollouts import disable_contacts, sapien_rollout

    row, result = load_timings(path, repeats)
    model = result.model
    result.disable_actuators()  # the reference runs with actuation disabled and commands generalized forces
    ref, _ = reference.matched(model, contact=False)
    disable_contacts(result)
    qpos0, qvel0, _ = reference.initial_state(model)
    command = np.zeros((steps, model.nv))
    mujoco_s, _ = _timed(lambda: reference.rollout(ref, qpos0, qvel0, steps, command))
    sapien_s, _ = _timed(lambda: sapien_rollout(result, model, qpos0, qvel0, command))
    set_ctrl_s, step_s = _set_ctrl_cost(result, steps)
    stages = _stage_costs(result, steps)
    law = result.controller.law()
    terms = _terms_cost(result, steps) if law == "mujoco_step" else None
    passes_us = _mujoco_pass_cost(result, steps) if law == "mujoco_step" else None
    batched = batch_costs(path, steps)
    return {
        **row,
        "steps": steps,
        "harness_mujoco_steps_per_s": steps / mujoco_s,
        "harness_sapien_steps_per_s": steps / sapien_s,
        "set_ctrl_us": 1e6 * set_ctrl_s / steps,
        "physx_step_us": 1e6 * step_s / steps,
        "set_ctrl_over_step": set_ctrl_s / step_s if step_s > 0 else None,
        "set_ctrl_stages_us": stages,
        "law": law,
        **({"terms": terms} if terms is not None else {}),
        **(
            {"mujoco_pass_us": passes_us, "mujoco_pass_over_step": passes_us / (1e6 * step_s / steps)}
            if passes_us is not None and step_s > 0
            else {}
        ),
        "batch": batched,
        "nbody": model.nbody,
        "nv": model.nv,
        "ngeom": model.ngeom,
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


def _mujoco_pass_cost(result, steps: int) -> float:
    """Microseconds per step of MuJoCo's own calls in MuJoCo's step law, alone: one forward pass of the rows' copy
    (as `rows.solve` runs it) and one integrator call, `steps` times at the state the last step left, on a data of
    their own. `set_ctrl` costs this plus the Python and SAPIEN calls around it: on the CPU, no work on the loader's
    side takes `set_ctrl` below it."""
    from loader.runtime.rows import solve

    whole = result.controller.whole
    rows, timestep = whole.rows, result.controller.timestep
    source = rows.data
    data = mujoco.MjData(rows.lent.model)
    for name in ("qpos", "qvel", "act", "ctrl", "qfrc_applied", "qacc_warmstart"):
        getattr(data, name)[:] = getattr(source, name)
    start = source.qvel.copy()
    with rows.lent as model:
        model.opt.disableflags = rows.solve_flags(actuated=True)
        t0 = time.perf_counter()
        for _ in range(steps):
            data.qvel[:] = start  # the integrator moved it
            solve(model, data, rows.with_contacts, timestep, rows.depenetration, not rows.mujocos)
            whole.integrate(model, data)
        seconds = time.perf_counter() - t0
    return 1e6 * seconds / steps


def _terms_cost(result, steps: int) -> dict:
    """`_set_ctrl_cost` and `_stage_costs` with the per-step terms giving the joint forces, on a model whose
    default is MuJoCo's own step (`Controller.use_mujoco_step`): what the step saves over the terms."""
    with result.controller.on_terms():
        set_ctrl_s, step_s = _set_ctrl_cost(result, steps)
        stages = _stage_costs(result, steps)
    return {
        "set_ctrl_us": 1e6 * set_ctrl_s / steps,
        "physx_step_us": 1e6 * step_s / steps,
        "set_ctrl_over_step": set_ctrl_s / step_s if step_s > 0 else None,
        "set_ctrl_stages_us": stages,
    }


def batch_costs(path: str, steps: int, counts: tuple[int, ...] = COPIES, terms: bool = False) -> dict[str, dict]:
    """Per batch size N: microseconds per copy per step in one `Batch.set_ctrl` of N copies (each in its own scene,
    contacts off, zero ctrl, the loader's default law or, `terms`, the per-step terms) and in the N PhysX steps,
    their ratio, and the stages that ran once for every copy."""
    from loader import Batch

    from .session import quiet_load

    results = [quiet_load(path) for _ in range(max(counts))]
    for result in results:
        result.set_contacts(False)
        if terms:
            result.controller.use_mujoco_step(False)
    out = {}
    for count in counts:
        batch = Batch(results[:count])
        ctrl = np.zeros((count, results[0].model.nu))
        set_ctrl_s = step_s = 0.0
        for _ in range(steps):
            t0 = time.perf_counter()
            batch.set_ctrl(ctrl)
            t1 = time.perf_counter()
            for result in batch.results:
                result.scene.step()
            set_ctrl_s, step_s = set_ctrl_s + t1 - t0, step_s + time.perf_counter() - t1
        out[str(count)] = {
            "set_ctrl_us_per_copy": 1e6 * set_ctrl_s / steps / count,
            "physx_step_us_per_copy": 1e6 * step_s / steps / count,
            "set_ctrl_over_step": set_ctrl_s / step_s if step_s > 0 else None,
            "batched_stages": list(batch.batched),
        }
    return out


def _stage_costs(result, steps: int) -> dict[str, float]:
    """Microseconds per step in each stage of `set_ctrl` (its `contribute` and `settle`), and in `controller`: the
    rest of the call (the state read, the command, the step record), over a second run of `steps` actuated steps at
    zero ctrl, timed apart from `_set_ctrl_cost` so that its figure carries no timer."""
    controller, ctrl = result.controller, np.zeros(result.model.nu)
    result.disable_actuators(False)
    timings, total = controller.timed(), 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        result.set_ctrl(ctrl)
        total += time.perf_counter() - t0
        result.scene.step()
    controller.timed(False)
    result.disable_actuators(True)
    out = {name: 1e6 * seconds / steps for name, seconds in sorted(timings.items(), key=lambda kv: -kv[1])}
    out["controller"] = 1e6 * total / steps - sum(out.values())
    return out


def _set_ctrl_ratio(figures: list[tuple[int, dict]], key: str = "set_ctrl_us") -> float | None:
    """All of `set_ctrl`'s time (or of the figure `key`) over all of PhysX's, from (steps, figures per step)
    pairs."""
    step_us = sum(steps * figure["physx_step_us"] for steps, figure in figures)
    return sum(steps * figure[key] for steps, figure in figures) / step_us if step_us > 0 else None


def totals(models: dict) -> dict:
    """Sums over the timed models (load over compile of the sums, steps per second over all steps), and the models
    whose load misses its target (`over_target`), cold and warm."""
    rows = [row for row in models.values() if "loader_load_s" in row]
    out = {"models": len(rows)}
    for key in ("mujoco_compile_s", "loader_load_s", "cold_mujoco_compile_s", "cold_loader_load_s"):
        out[key] = sum(row[key] for row in rows)
    out["load_over_compile"] = _ratio(out["loader_load_s"], out["mujoco_compile_s"])
    out["cold_load_over_compile"] = _ratio(out["cold_loader_load_s"], out["cold_mujoco_compile_s"])
    steps = sum(row["steps"] for row in rows)
    for side in ("mujoco", "sapien"):
        seconds = sum(row["steps"] / row[f"harness_{side}_steps_per_s"] for row in rows)
        out[f"harness_{side}_steps_per_s"] = steps / seconds if seconds > 0 else None
    out["set_ctrl_over_step"] = _set_ctrl_ratio([(row["steps"], row) for row in rows])
    driven = [row for row in rows if "terms" in row]
    if driven:  # the models MuJoCo's step drives: set_ctrl over PhysX's step with it, and with the terms
        out["mujoco_step"] = {
            "models": len(driven),
            "set_ctrl_over_step": _set_ctrl_ratio([(row["steps"], row) for row in driven]),
            "terms_set_ctrl_over_step": _set_ctrl_ratio([(row["steps"], row["terms"]) for row in driven]),
            "mujoco_pass_over_step": _set_ctrl_ratio([(row["steps"], row) for row in driven], "mujoco_pass_us"),
        }
    batched = [row["batch"] for row in rows if "batch" in row]
    out["batch_set_ctrl_over_step"] = {
        count: sum(b[count]["set_ctrl_us_per_copy"] for b in batched)
        / sum(b[count]["physx_step_us_per_copy"] for b in batched)
        for count in (batched[0] if batched else {})
    }
    out["over_target"] = {
        "warm": [name for name, row in models.items() if over_target(row, "")],
        "cold": [name for name, row in models.items() if over_target(row, "cold_")],
    }
    return out


def bench(entries: list[ModelEntry], out: Path, steps: int = 200, repeats: int = REPEATS) -> dict:
    """Benchmark every resolvable entry (the warm side in this process) and write the JSON document atomically."""
    models = {}
    for entry in entries:
        resolved = corpus.resolve(entry)
        if resolved.path is None:
            models[entry.id] = {"skipped": resolved.skip_reason}
            continue
        try:
            models[entry.id] = bench_model(str(resolved.path), steps, repeats)
        except Exception as exc:  # noqa: BLE001 - one broken model does not end the benchmark
            models[entry.id] = {"error": f"{type(exc).__name__}: {exc}"}
    doc = {
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "versions": versions(),
        "repeats": repeats,
        "target_load_over_compile": TARGET,
        "tiny_compile_s": TINY_COMPILE_S,
        "target_tiny_beyond_compile_s": TINY_BEYOND_S,
        "models": models,
        "totals": totals(models),
    }
    atomic_write_json(Path(out), doc)
    return doc
