"""What one mutant does to the loader, judged with MuJoCo as the oracle.

Good outcomes: `typed_error` (the loader raised MJCFError or another of its typed errors), `loaded_right` (loaded;
structure, kinematics and inertia tiers pass; 50 steps under random ctrl stay finite and within the divergence
bound MuJoCo's own run sets), `shared_divergence` (MuJoCo's own run blows up too, or
warns that its joint-space inertia is singular).
Bad outcomes: `crash` (the process died), `hang` (past its timeout in its own CPU time, or blocked), `untyped_error`
(any other exception), `silently_wrong` (loaded where MuJoCo rejects the document, or a static tier is
`WRONG_FACTOR` times past its tolerance), `divergence` (SAPIEN leaves
the finite, physical states while MuJoCo does not).
`classify` runs in the process it is called from; `start` runs it in a forked child with a timeout, so a
crash or a hang is an outcome, not the end of the session. Tested by tests/test_robustness.py."""

from __future__ import annotations

import math
import multiprocessing
import os
import resource
import signal
import time
import traceback
import warnings
from dataclasses import asdict, dataclass

import numpy as np

GOOD = ("typed_error", "loaded_right", "shared_divergence")
BAD = ("crash", "hang", "untyped_error", "silently_wrong", "divergence")
STATIC_TIERS = ("structure", "kinematics", "inertia")
STEPS = 50
# a static tier is silently wrong at this multiple of its conformance tolerance: the session asks whether a load is
# right in kind (a body 1e23 m off, a joint turned the wrong way); float32 composing a 200-link chain's poses
# is 1e-5 m off and judged by the conformance tiers, not here (tests/test_robustness.py)
WRONG_FACTOR = 100.0


@dataclass(frozen=True)
class Outcome:
    """One mutant's outcome, the stage it was decided in (reference, load, static, step, process), and why."""

    outcome: str
    stage: str
    detail: str = ""

    @property
    def bad(self) -> bool:
        return self.outcome in BAD

    def to_dict(self) -> dict:
        return asdict(self)


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"[:300]


def _reference(path: str):
    """MuJoCo's compile and first forward pass of the document, or the message it rejects it with."""
    import mujoco

    try:
        model = mujoco.MjModel.from_xml_path(path)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
    except Exception as error:  # noqa: BLE001 - MuJoCo's own verdict: any error it raises is a rejection
        return None, _first_line(error)
    return model, ""


def _ctrl(model, rng: np.random.Generator) -> np.ndarray:
    low = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 0], -1.0)
    high = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 1], 1.0)
    low, high = np.nan_to_num(low, nan=-1.0), np.nan_to_num(high, nan=1.0)
    return np.clip(rng.uniform(-1.0, 1.0, model.nu) * np.maximum(np.abs(low), np.abs(high)), low, high)


def _steps(result, model, seed: int, tolerances) -> Outcome:
    """Both simulators from qpos0 under the same random ctrl; SAPIEN judged against MuJoCo's own run."""
    import mujoco

    from loader import DivergenceError

    from ..divergence import SpeedBound, first_divergence

    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    qpos, qvel, reference = [], [], []
    gone = (np.full(model.nq, np.nan), np.full(model.nv, np.nan))  # SAPIEN's state once `step` refused it
    diverged = False
    for _ in range(STEPS):
        ctrl = _ctrl(model, rng)
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
        try:
            if not diverged:
                result.step(ctrl)
        except DivergenceError:  # the loader's verdict on a state no longer finite: judged as such below
            diverged = True
        q, v = gone if diverged else result.get_state()
        qpos.append(q), qvel.append(v), reference.append(data.qvel.copy())
    warned = {
        w: data.warning[getattr(mujoco.mjtWarning, f"mjWARN_{w.upper()}")].number > 0 for w in ("badqacc", "inertia")
    }  # MuJoCo's own verdict on its run: it blew up, or M is singular
    if any(warned.values()) or not np.isfinite(data.qvel).all():
        return Outcome(
            "shared_divergence",
            "step",
            "MuJoCo's own run " + ("reports a singular inertia" if warned["inertia"] else "blows up (bad qacc)"),
        )
    found = first_divergence(
        "random ctrl",
        np.array(qpos),
        np.array(qvel),
        np.array(reference),
        SpeedBound.from_tolerances(tolerances),
        model.opt.timestep,
    )
    if found is not None:
        return Outcome("divergence", "step", found.text())
    return Outcome("loaded_right", "step")


def classify(path: str, seed: int = 0) -> Outcome:
    """The outcome of loading the document at `path` and stepping it (see the module's docstring)."""
    from loader import ControlError, MJCFError

    from ..session import quiet_load
    from ..tiers import TIERS
    from ..tolerances import load as load_tolerances

    model, rejected = _reference(path)
    try:
        result = quiet_load(path)
    except (MJCFError, ControlError) as error:
        return Outcome("typed_error", "load", _first_line(error))
    except Exception as error:  # noqa: BLE001 - the bad outcome this session exists to find
        return Outcome("untyped_error", "load", _first_line(error) + " | " + traceback.format_exc(limit=-3)[-600:])
    if model is None:
        return Outcome("silently_wrong", "load", f"loaded although MuJoCo rejects the document: {rejected}")
    tolerances = load_tolerances()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for tier in STATIC_TIERS:
                report = TIERS[tier](result, model, seed, tolerances)  # against MuJoCo's own compile
                worst = max(
                    report.metrics,
                    key=lambda m: m.max / m.tolerance if m.tolerance else (0.0 if m.max == 0 else np.inf),
                    default=None,
                )
                if worst is not None and not worst.max <= WRONG_FACTOR * worst.tolerance:
                    return Outcome(
                        "silently_wrong", "static", f"{tier} {worst.name} {worst.max:.3g} (tol {worst.tolerance:.3g})"
                    )
            return _steps(result, model, seed, tolerances)
    except ControlError as error:  # a command MuJoCo refuses too (a ctrlrange beyond mjMAXVAL)
        return Outcome("typed_error", "step", _first_line(error))
    except MJCFError as error:
        return Outcome("untyped_error", "step", "a load error raised after the load: " + _first_line(error))
    except Exception as error:  # noqa: BLE001 - as at the load
        return Outcome(
            "untyped_error", "static/step", _first_line(error) + " | " + traceback.format_exc(limit=-3)[-600:]
        )


def _child(path: str, seed: int, conn) -> None:
    with open(os.devnull, "w") as null:  # MuJoCo's and PhysX's own prints stay out of the session's output
        os.dup2(null.fileno(), 1), os.dup2(null.fileno(), 2)
    warnings.simplefilter("ignore")
    conn.send(classify(path, seed).to_dict())
    conn.close()


WALL_FACTOR = 4.0  # a child that uses no CPU (blocked) is a hang after this many times its timeout in wall time


def _limited(target, cpu_seconds: float, path: str, seed: int, conn) -> None:
    """`target` under a CPU-time limit: the kernel stops the child (SIGXCPU) past `cpu_seconds` of its own CPU."""
    limit = max(1, math.ceil(cpu_seconds))
    resource.setrlimit(resource.RLIMIT_CPU, (limit, limit + 5))
    target(path, seed, conn)


class Running:
    """`classify` running in a forked child (`start`): `finish()` gives its outcome once there is one, `join()`
    waits for it. A child that dies is a `crash`; one past its timeout in its own CPU time (so that children
    slowed by others on a busy machine are not hangs), or past WALL_FACTOR times it in wall time, a `hang`."""

    def __init__(self, path: str, seed: int, timeout: float, target=_child) -> None:
        ctx = multiprocessing.get_context("fork")  # the parent's imports are shared: a child costs milliseconds
        self.receive, send = ctx.Pipe(duplex=False)
        self.child = ctx.Process(target=_limited, args=(target, timeout, path, seed, send), daemon=True)
        self.timeout = timeout
        self.deadline = time.monotonic() + WALL_FACTOR * timeout
        self.child.start()
        send.close()

    def left(self) -> float:
        return max(0.0, self.deadline - time.monotonic())

    def finish(self) -> Outcome | None:
        if self.receive.poll():
            try:
                outcome = Outcome(**self.receive.recv())
            except EOFError:
                self.child.join(5.0)
                if self.child.exitcode == -signal.SIGXCPU:
                    outcome = Outcome("hang", "process", f"no outcome after {self.timeout:.0f} s of CPU time")
                else:
                    outcome = Outcome("crash", "process", f"the process died (exit code {self.child.exitcode})")
        elif self.left() <= 0.0:
            outcome = Outcome("hang", "process", f"no outcome after {WALL_FACTOR * self.timeout:.0f} s")
        else:
            return None
        self.close()
        return outcome

    def join(self) -> Outcome:
        while (outcome := self.finish()) is None:
            self.receive.poll(self.left())
        return outcome

    def close(self) -> None:
        self.receive.close()
        if self.child.is_alive():
            self.child.kill()
        self.child.join()


def start(path: str, seed: int = 0, timeout: float = 60.0, target=_child) -> Running:
    """`classify(path, seed)` in a forked child with a timeout."""
    return Running(path, seed, timeout, target)
