"""The timeline: `sim_time` (seconds), which the blueprint pins; a step is `sim_time / timestep`, so no second
timeline repeats it on every row. Kinematics configurations are on `configuration`, a separate timeline the
blueprint does not open."""

from __future__ import annotations

import numpy as np
import rerun as rr

TIMELINE = "sim_time"


def times(time: np.ndarray) -> list:
    """Index column of a rollout sampled at `time` (seconds), one row per step."""
    return [rr.TimeColumn(TIMELINE, duration=np.asarray(time, dtype=float))]


def strided(count: int, stride: int, dt: float) -> list:
    """Index column of `count` samples taken every `stride` steps."""
    return [rr.TimeColumn(TIMELINE, duration=np.arange(count) * stride * dt)]
