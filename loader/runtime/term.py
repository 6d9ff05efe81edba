"""The contract every per-step term keeps with the controller (`controller.py`): a name from `STAGES`, the hooks
below with their no-op defaults, and nothing else the controller looks for. A term is planned once at load by its
module's `plan_*` function, compiled into arrays by `compile`, and run by `contribute` on every `set_ctrl`, in stage
order (tests/test_loader_structure.py::test_a_toy_term_joins_the_controller_through_the_public_contract)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

if TYPE_CHECKING:
    from .dof_step import DofLayout, Step


@dataclass(frozen=True)
class Compilation:
    """What a term's `compile` reads: where each DoF sits (`layout`), the passive drive laws as arrays (rows
    stiffness, damping, constant, force limit; one column per drive DoF) and the names of the terms planned (on
    or off)."""

    layout: DofLayout
    passive: np.ndarray
    planned: frozenset[str]


@dataclass(frozen=True)
class Handover:
    """What `release` needs to hand the joints to a caller that drives them itself: the PhysX joints per
    articulation, the articulations and the scene's timestep."""

    joints: list[list]
    articulations: list
    timestep: float


class Term:
    """One per-step law. `idle`: compiled to nothing to do (skipped by `set_ctrl`, still released); `applied`: the
    root wrenches it added this step (the `momentum` term accounts for them)."""

    name: ClassVar[str] = ""
    idle: bool = False

    @property
    def applied(self) -> list | tuple:
        return ()

    def compile(self, compilation: Compilation) -> None:
        """Arrays from the plan; runs before the first `set_ctrl` and after every edit or switch."""

    def contribute(self, step: Step) -> None:
        """Add this term's law to the step (forces, drive laws), or act on PhysX directly."""
        raise NotImplementedError(f"the {self.name} term has no per-step law")

    def batch(self, step: Step, steps: list[Step], terms: list[Term]) -> bool:
        """This stage for every copy of a `Batch` at once: `step`'s arrays carry a leading copy axis (`law`: rows,
        copies, drive DoFs), `steps` are each copy's record (views of its rows) and `terms` each copy's own term,
        for what acts on PhysX. False, having changed nothing: each copy's term runs `contribute` on its own
        record instead (the default)."""
        return False

    def settle(self, articulations: list, wrenches: list) -> None:
        """After a physics step, before the state is read (`wrenches`: every term's `applied`)."""

    def forget(self) -> None:
        """The state was set from outside: nothing carries over from the last step."""

    def contacts(self, enabled: bool) -> None:
        """SAPIEN's contacts were switched on or off."""

    def velocity_links(self, articulations: list) -> list:
        """The links whose velocities this term reads (they are refreshed before it runs)."""
        return []

    def release(self, handover: Handover) -> None:
        """Hand the joints to a caller that drives them itself: undo what only `set_ctrl` keeps right."""

    def removed(self, joints: list[list]) -> None:
        """Switched off (`Controller.without`): undo what it holds in PhysX."""

    def set_active(self, equality: int, active: bool) -> None:
        """MuJoCo's `data.eq_active[equality] = active`."""

    def reset_active(self) -> None:
        """Every equality back to the model's `eq_active0`."""

    def spare(self, model, data) -> bool:
        """Offered `data`, a MuJoCo data of `model` that nothing else reads any more (the load's own forward pass at
        qpos0, once the build has read it): True where this term keeps it as its own, instead of making one."""
        return False


class LinkForces(Term):
    """A term that adds forces to links: PhysX accumulates them until the step, so they are added once per physics
    step (the first `set_ctrl` of it)."""

    def contribute(self, step: Step) -> None:
        if step.advance:
            self.apply(step.articulations)

    def apply(self, articulations: list) -> None:
        raise NotImplementedError
