"""MuJoCo's affine actuator force law over many actuators at once: gain x input + bias0 + bias1 x length + bias2 x
velocity, clamped to forcerange (each actuator in actuator space, before gear). The arrays are planned once from the
actuator maps; `runtime/actuators.py` applies them every step."""

from __future__ import annotations

import numpy as np

from ..build.actuators import ActuatorMap


class ActuatorLaws:
    """Columns of actuator parameters, one per actuator of `indices` (MuJoCo's actuator ids)."""

    def __init__(self, actuators: list[ActuatorMap], indices: list[int]):
        chosen = [actuators[a] for a in indices]
        self.indices = np.array(indices, dtype=int)
        self.gear = np.array([x.gear for x in chosen], dtype=np.float64)
        self.gain = np.array([x.gain for x in chosen], dtype=np.float64)
        self.bias = np.array([x.bias for x in chosen], dtype=np.float64).reshape(-1, 3).T.copy()
        self.low = np.array([x.forcerange[0] if x.forcerange else -np.inf for x in chosen], dtype=np.float64)
        self.high = np.array([x.forcerange[1] if x.forcerange else np.inf for x in chosen], dtype=np.float64)
        self.damping = np.array([x.damping for x in chosen], dtype=np.float64)  # gear^2 kv

    def __len__(self) -> int:
        return int(self.indices.size)

    def unclamped(self, inputs: np.ndarray, length: np.ndarray, velocity: np.ndarray, chosen=slice(None)):
        """MuJoCo's force law (before gear and clamp) of the `chosen` actuators."""
        bias = self.bias
        return (self.gain[chosen] * inputs + bias[0][chosen] + bias[1][chosen] * length
                + bias[2][chosen] * velocity)

    def clamped(self, unclamped: np.ndarray, chosen=slice(None)) -> np.ndarray:
        """The force clamped to forcerange (no range: unchanged)."""
        return np.minimum(np.maximum(unclamped, self.low[chosen]), self.high[chosen])
