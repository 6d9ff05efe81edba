"""The timelines: `step` (sequence) and `sim_time` (seconds), which the blueprint pins. Kinematics configurations
are on `configuration`, a separate timeline the blueprint does not open."""

from __future__ import annotations

import numpy as np
import rerun as rr

TIMELINE = "sim_time"


def times(time: np.ndarray) -> list:
    """Index columns of a rollout sampled at `time` (seconds), one row per step."""
    steps = np.arange(time.size)
    return [rr.TimeColumn("step", sequence=steps), rr.TimeColumn(TIMELINE, duration=time)]


def strided(count: int, stride: int, dt: float) -> list:
    """Index columns of `count` samples taken every `stride` steps."""
    steps = np.arange(count) * stride
    return [rr.TimeColumn("step", sequence=steps), rr.TimeColumn(TIMELINE, duration=steps * dt)]
