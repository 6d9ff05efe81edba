"""LoadResult: what `MJCFLoader.load` built, and the façade a caller steps it through (state, reset, set_ctrl,
step, release, contacts, equalities), delegating the per-step work to `result.controller` (`runtime/`).

The state goes in and out in MuJoCo's layout (`get_state`, `set_state`, `keyframe_state`) through `result.mapping`,
so a caller never handles SAPIEN's per-articulation joint order
(tests/test_loader_structure.py::test_the_state_api_round_trips)."""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from .errors import Approximation, ControlError, Unsupported, command_vector
from .model.actuators import ActuatorMap
from .model.equalities import EqualityLink
from .model.mapping import Mapping
from .plan.camera import CameraConfig, SiteConfig
from .plan.texture import MJCFTexture
from .runtime import contacts
from .runtime.controller import Controller


@dataclass
class LoadResult:
    """Everything `MJCFLoader.load` built, with the compiled MuJoCo model it came from (`model`, the caller's to read
    and edit: the per-step terms run on their own copy, and an edit reaches them only through `replan()`)."""

    path: str
    spec: mujoco.MjSpec
    scene: sapien.Scene
    articulations: list[sapien.physx.PhysxArticulation]
    actors: list[sapien.Entity]
    cameras: list[CameraConfig]
    sites: dict[str, SiteConfig]
    textures: list[MJCFTexture]
    mapping: Mapping
    controller: Controller = field(repr=False)  # the per-step terms (`runtime/`)
    unsupported: list[Unsupported] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)
    actuators: list[ActuatorMap] = field(default_factory=list)
    equalities: list[EqualityLink] = field(default_factory=list)
    replanner: Callable[[LoadResult, mujoco.MjModel], tuple] | None = field(default=None, repr=False)  # `replan`
    contacts: str = "mujoco"  # whose the contacts between the model's own shapes are (`MJCFLoader.contacts`)
    held_ctrl: np.ndarray | None = field(default=None, init=False, repr=False)  # the ctrl `step` holds
    _saved_collision_groups: list | None = field(default=None, init=False, repr=False)  # while contacts are off
    _model: mujoco.MjModel | None = field(default=None, init=False, repr=False)  # the caller's copy, made on demand

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled MuJoCo model, the caller's own: a copy of the one the per-step terms run on, made on first
        access. Editing it changes nothing SAPIEN does until `replan()`."""
        if self._model is None:
            self._model = copy.copy(self.controller.model)
        return self._model

    def replan(self) -> None:
        """Plan the per-step terms again from `model` as the caller has edited it: actuator gains and ranges,
        joint damping, stiffness and friction, limits' solref, tendons, equalities' solref and activity, the
        integrator, the flags. What the load built once (bodies, inertia, shapes, the joints' PhysX ranges, the
        D6 joints of equalities, the solver iterations, the scene's timestep) stays as built: load again for those.
        The state is kept, and contacts stay off where `set_contacts(False)` turned them off; activations are kept
        where the model's actuators are the same."""
        if self.replanner is None:
            raise ControlError(f"{self.path}: this result was not built to be planned again")
        act = self.act
        self.controller.release()
        self.actuators, self.controller = self.replanner(self, copy.copy(self.model))
        if self._saved_collision_groups is not None:  # the new terms start with SAPIEN's contacts on
            self.controller.contacts(False)
        if self.controller.activation is not None and act.size == self.controller.model.na:
            self.controller.activation.reset(act)
        self.set_ctrl(self.held_ctrl, advance=False)

    @property
    def articulation(self) -> sapien.physx.PhysxArticulation | None:
        """The first articulation (what ManiSkill's loader returns)."""
        return self.articulations[0] if self.articulations else None

    def reset(self, key: int | str | None = None) -> None:
        """Put the SAPIEN scene into the state (and ctrl and activation) of keyframe `key`, or qpos0 with zero
        ctrl and activation; equalities back to their initial active state (as MuJoCo's mj_resetData)."""
        if key is not None:
            self.keyframe(key)  # an unknown one raises before anything changes
        self.controller.reset_equalities()
        self.mapping.set_state(self.articulations, *self.keyframe_state(key))
        self.controller.forget()
        self.set_act(None if key is None else self.keyframe(key).act)
        self.set_ctrl(self.ctrl(key), advance=False)

    @property
    def act(self) -> np.ndarray:
        """MuJoCo's `data.act`: the activation of actuators with dynamics (size `model.na`)."""
        activation = self.controller.activation
        return activation.act.copy() if activation is not None else np.zeros(self.controller.model.na)

    def set_act(self, act) -> None:
        """Set the activation (MuJoCo's `data.act`; None: zeros), as part of setting a MuJoCo state."""
        if self.controller.activation is not None:
            self.controller.activation.reset(act)

    def set_ctrl(self, ctrl, qfrc_applied=None, advance: bool = True) -> None:
        """Apply a MuJoCo control vector (size nu, or None for zeros) to the SAPIEN articulations: drive targets
        and joint forces.

        Clamped to ctrlrange as MuJoCo does. It writes every articulation's `qf` (SAPIEN keeps it across steps);
        clamps, tendons, friction, limits and explicit gains depend on the state, so call it before every step, as
        MuJoCo reads `ctrl` every step. It owns the joint drives: it rewrites only settings it changed.
        Actuators with activation dynamics use the activation and take it one step further (`advance`): call it
        once per step, or with `advance=False` to re-apply the same step. `qfrc_applied`: MuJoCo's generalized
        force (size nv) on top; write it here rather than with `set_qf`, which would overwrite the loader's terms.
        A vector of the wrong size or with a non-finite entry raises ControlError and changes nothing.
        """
        model = self.controller.model
        ctrl = command_vector(self.path, "ctrl", ctrl, model.nu, "actuators (nu)")
        qfrc_applied = command_vector(self.path, "qfrc_applied", qfrc_applied, model.nv, "DoFs (nv)")
        self.controller.set_ctrl(ctrl, qfrc_applied, advance)

    def step(self, ctrl=None, substeps: int = 1, qfrc_applied=None) -> None:
        """`substeps` physics steps under one MuJoCo ctrl (None: the last one given), `set_ctrl` before each:
        a controller running slower than the simulation keeps the state-dependent terms (friction, tendons,
        force clamps, explicit gains, activations) of every step, as MuJoCo with the same ctrl held would."""
        model = self.controller.model
        qfrc_applied = command_vector(self.path, "qfrc_applied", qfrc_applied, model.nv, "DoFs (nv)")
        if ctrl is not None:
            self.held_ctrl = command_vector(self.path, "ctrl", ctrl, model.nu, "actuators (nu)").copy()
        for _ in range(substeps):
            self.set_ctrl(self.held_ctrl, qfrc_applied)
            self.scene.step()

    def set_equality_active(self, key: int | str, active: bool) -> None:
        """MuJoCo's `data.eq_active[key] = active` (key: the equality's index or name); the next `set_ctrl`
        applies it. ValueError for an equality the loader did not map."""
        model = self.controller.model
        index = key if isinstance(key, int) else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, key)
        if not 0 <= index < model.neq:
            raise KeyError(f"{self.path}: no equality {key!r} (the model has {model.neq})")
        link = next((e for e in self.equalities if e.index == index), None)
        if link is None or not link.mapped:
            raise ValueError(f"{self.path}: equality {key!r} is not mapped, so it cannot be switched")
        self.controller.set_equality_active(index, active)

    def release(self) -> None:
        """Leave the joints to a controller that sets PhysX drive targets and never calls `set_ctrl` (ManiSkill's):
        passive drives, MuJoCo's armature, no joint forces; rows, tendons, clamps and fluid are not carried."""
        self.controller.release()

    def set_contacts(self, enabled: bool) -> None:
        """Turn every collision shape of this load off (contact-free simulation) or back on with the groups it had;
        the state is left as it is. Safe in any order with stepping (a plain restore of zeroed collision groups
        can crash PhysX: `runtime.contacts`)."""
        self.controller.contacts(enabled)
        if not enabled and self._saved_collision_groups is None:
            self._saved_collision_groups = contacts.disable_contacts(self)
        elif enabled and self._saved_collision_groups is not None:
            contacts.restore_contacts(self, self._saved_collision_groups)
            self._saved_collision_groups = None

    def collision_groups(self, shape) -> list[int]:
        """A shape's collision words as the model's filter sets them (the words PhysX's contacts use), also while
        `set_ctrl` holds the model's own contacts as MuJoCo's and gives the shapes other words
        (docs/mapping.md#contacts-as-rows)."""
        rows = self.controller.term("rows")
        own = None if rows is None else rows.own
        return own.groups(shape) if own is not None else list(shape.get_collision_groups())

    def disable_actuators(self, disabled: bool = True) -> None:
        """Take every actuator out (MuJoCo's `<flag actuation="disable"/>`): joints keep only their passive
        spring-damper drives and `qf` is cleared; `disable_actuators(False)` puts them back."""
        (self.controller.without if disabled else self.controller.restore)("actuators")
        self.controller.set_ctrl(None, advance=False)

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The live SAPIEN state as MuJoCo's (qpos of size nq, qvel of size nv)."""
        self.controller.settle()
        return self.mapping.get_state(self.articulations)

    def set_state(self, qpos, qvel=None) -> None:
        """Put MuJoCo's (qpos, qvel) (qvel None: at rest) into the articulations, as assigning MuJoCo's `data.qpos`
        and `data.qvel` does; ctrl and activations stay as they are (`reset` sets those too). A vector of the wrong
        size or with a non-finite entry raises ControlError and changes nothing."""
        model = self.controller.model
        qpos = command_vector(self.path, "qpos", qpos, model.nq, "qpos entries (nq)")
        qvel = command_vector(self.path, "qvel", qvel, model.nv, "DoFs (nv)")
        self.mapping.set_state(self.articulations, qpos, qvel)
        self.controller.forget()

    def keyframe_state(self, key: int | str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo (qpos, qvel) of keyframe `key` (index or name), or of qpos0 at rest when `key` is None."""
        model = self.controller.model
        if key is None:
            return model.qpos0.copy(), np.zeros(model.nv)
        keyframe = self.keyframe(key)
        return keyframe.qpos.copy(), keyframe.qvel.copy()

    def state(self, key: int | str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Deprecated: the keyframe's state, which the name did not say; use `keyframe_state` (or `get_state` for the
        live state). Kept for one version."""
        warnings.warn(
            "LoadResult.state(key) is deprecated: use keyframe_state(key) for a keyframe's state or "
            "get_state() for the live one",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.keyframe_state(key)

    def ctrl(self, key: int | str | None = None) -> np.ndarray:
        """MuJoCo ctrl of keyframe `key`, or zeros (MuJoCo's initial ctrl) when `key` is None."""
        return np.zeros(self.controller.model.nu) if key is None else self.keyframe(key).ctrl.copy()

    def keyframe(self, key: int | str):
        """MuJoCo's keyframe `key` (index or name); ControlError naming the keyframes the model has."""
        model = self.controller.model
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) or str(k) for k in range(model.nkey)]
        try:
            return model.keyframe(key)
        except (KeyError, IndexError) as error:
            have = ", ".join(repr(n) for n in names) if names else "none"
            raise ControlError(f"{self.path}: no keyframe {key!r}; the model's keyframes: {have}") from error
