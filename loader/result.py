"""LoadResult: what `MJCFLoader.load` built, and the façade a caller steps it through (state, reset, set_ctrl,
step, release, contacts, equalities), delegating the per-step work to `result.controller` (`runtime/`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import sapien

from .build.actuators import ActuatorMap
from .build.camera import CameraConfig, SiteConfig
from .build.equalities import EqualityLink
from .build.mapping import Mapping
from .build.texture import MJCFTexture
from .errors import Unsupported, command_vector
from .runtime import contacts
from .runtime.controller import Controller
from .state import MuJoCoState


@dataclass
class LoadResult(MuJoCoState):
    """Everything `MJCFLoader.load` built, with the compiled MuJoCo model it came from; the state in MuJoCo's layout
    through `get_state`, `set_state`, `keyframe_state` (`loader/state.py`)."""

    path: str
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    scene: sapien.Scene
    articulations: list[sapien.physx.PhysxArticulation]
    actors: list[sapien.Entity]
    cameras: list[CameraConfig]
    sites: dict[str, SiteConfig]
    textures: list[MJCFTexture]
    mapping: Mapping
    controller: Controller = field(repr=False)  # the per-step terms (`runtime/`)
    unsupported: list[Unsupported] = field(default_factory=list)
    approximations: list[Unsupported] = field(default_factory=list)
    actuators: list[ActuatorMap] = field(default_factory=list)
    equalities: list[EqualityLink] = field(default_factory=list)
    held_ctrl: np.ndarray | None = field(default=None, init=False, repr=False)  # the ctrl `step` holds
    _saved_collision_groups: list | None = field(default=None, init=False, repr=False)  # while contacts are off

    @property
    def articulation(self) -> sapien.physx.PhysxArticulation | None:
        """The first articulation (what ManiSkill's loader returns)."""
        return self.articulations[0] if self.articulations else None

    def reset(self, key: int | str | None = None) -> None:
        """Put the SAPIEN scene into the state (and ctrl and activation) of keyframe `key`, or qpos0 with zero
        ctrl and activation; equalities back to their initial active state (as MuJoCo's mj_resetData)."""
        for link in self.equalities:
            if link.soft is not None:
                link.soft.set_active(bool(self.model.eq_active0[link.soft.equality]))
        rows = self.controller.term("rows")
        if rows is not None:
            rows.reset_active()
        self.mapping.set_state(self.articulations, *self.keyframe_state(key))
        self.controller.forget()
        self.set_act(None if key is None else self.model.keyframe(key).act)
        self.set_ctrl(self.ctrl(key), advance=False)

    @property
    def act(self) -> np.ndarray:
        """MuJoCo's `data.act`: the activation of actuators with dynamics (size `model.na`)."""
        activation = self.controller.activation
        return activation.act.copy() if activation is not None else np.zeros(self.model.na)

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
        ctrl = command_vector(self.path, "ctrl", ctrl, self.model.nu, "actuators (nu)")
        qfrc_applied = command_vector(self.path, "qfrc_applied", qfrc_applied, self.model.nv, "DoFs (nv)")
        self.controller.set_ctrl(ctrl, qfrc_applied, advance)

    def step(self, ctrl=None, substeps: int = 1, qfrc_applied=None) -> None:
        """`substeps` physics steps under one MuJoCo ctrl (None: the last one given), `set_ctrl` before each:
        a controller running slower than the simulation keeps the state-dependent terms (friction, tendons,
        force clamps, explicit gains, activations) of every step, as MuJoCo with the same ctrl held would."""
        qfrc_applied = command_vector(self.path, "qfrc_applied", qfrc_applied, self.model.nv, "DoFs (nv)")
        if ctrl is not None:
            self.held_ctrl = command_vector(self.path, "ctrl", ctrl, self.model.nu, "actuators (nu)").copy()
        for _ in range(substeps):
            self.set_ctrl(self.held_ctrl, qfrc_applied)
            self.scene.step()

    def set_equality_active(self, key: int | str, active: bool) -> None:
        """MuJoCo's `data.eq_active[key] = active` (key: the equality's index or name); the next `set_ctrl`
        applies it. ValueError for an equality the loader did not map."""
        index = key if isinstance(key, int) else mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_EQUALITY, key)
        if not 0 <= index < self.model.neq:
            raise KeyError(f"{self.path}: no equality {key!r} (the model has {self.model.neq})")
        link = next((e for e in self.equalities if e.index == index), None)
        if link is None or not link.mapped:
            raise ValueError(f"{self.path}: equality {key!r} is not mapped, so it cannot be switched")
        if link.kind == "MuJoCo row":
            self.controller.term("rows").set_active(index, active)
        if link.soft is not None:
            link.soft.set_active(active)

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

    def disable_actuators(self, disabled: bool = True) -> None:
        """Take every actuator out (MuJoCo's `<flag actuation="disable"/>`): joints keep only their passive
        spring-damper drives and `qf` is cleared; `disable_actuators(False)` puts them back."""
        (self.controller.without if disabled else self.controller.restore)("actuators")
        self.controller.set_ctrl(None, advance=False)
