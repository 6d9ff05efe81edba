"""The state of a load in MuJoCo's layout: the live (qpos, qvel) of the SAPIEN articulations, and the keyframes'.

`LoadResult` takes these methods from `MuJoCoState`; they read and write through `result.mapping`, so a caller never
handles SAPIEN's per-articulation joint order (tests/test_loader_structure.py::test_the_state_api_round_trips).
"""

from __future__ import annotations

import warnings

import numpy as np

from .errors import command_vector


class MuJoCoState:
    """State access for `LoadResult` (which holds `path`, `model`, `mapping`, `articulations` and `controller`)."""

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The live SAPIEN state as MuJoCo's (qpos of size nq, qvel of size nv)."""
        self.controller.settle()
        return self.mapping.get_state(self.articulations)

    def set_state(self, qpos, qvel=None) -> None:
        """Put MuJoCo's (qpos, qvel) (qvel None: at rest) into the articulations, as assigning MuJoCo's `data.qpos`
        and `data.qvel` does; ctrl and activations stay as they are (`reset` sets those too). A vector of the wrong
        size or with a non-finite entry raises ControlError and changes nothing."""
        qpos = command_vector(self.path, "qpos", qpos, self.model.nq, "qpos entries (nq)")
        qvel = command_vector(self.path, "qvel", qvel, self.model.nv, "DoFs (nv)")
        self.mapping.set_state(self.articulations, qpos, qvel)
        self.controller.forget()

    def keyframe_state(self, key: int | str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo (qpos, qvel) of keyframe `key` (index or name), or of qpos0 at rest when `key` is None."""
        if key is None:
            return self.model.qpos0.copy(), np.zeros(self.model.nv)
        keyframe = self.model.keyframe(key)
        return keyframe.qpos.copy(), keyframe.qvel.copy()

    def state(self, key: int | str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Deprecated: the keyframe's state, which the name did not say; use `keyframe_state` (or `get_state` for the
        live state). Kept for one version."""
        warnings.warn("LoadResult.state(key) is deprecated: use keyframe_state(key) for a keyframe's state or "
                      "get_state() for the live one", DeprecationWarning, stacklevel=2)
        return self.keyframe_state(key)

    def ctrl(self, key: int | str | None = None) -> np.ndarray:
        """MuJoCo ctrl of keyframe `key`, or zeros (MuJoCo's initial ctrl) when `key` is None."""
        return np.zeros(self.model.nu) if key is None else self.model.keyframe(key).ctrl.copy()
