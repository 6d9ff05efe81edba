"""Several copies of one model, each in its own SAPIEN scene, driven by one `set_ctrl` with a command per copy.

Each copy keeps its own controller (its MuJoCo data for the rows, its momentum, its activations, its PhysX writes);
the step's record stacks the copies' arrays on a leading axis (`Step.q` copies x DoFs, `Step.law` rows x copies x
drive DoFs), each copy's record being views of its rows. A stage whose law is only arrays runs once for every copy
(`Term.batch`); the others run per copy on its own record, in the same stage order. A copy's drives, forces and
state come out exactly as its own `set_ctrl` would leave them
(tests/test_loader_batch.py::test_a_batch_steps_each_copy_as_its_own_set_ctrl).
"""

from __future__ import annotations

import numpy as np

from ..errors import ControlError, command_vector
from .dof_step import Step
from .momentum import settle_copies, stacked_passes


class Batch:
    """`results`: the `LoadResult`s of one MJCF file, one per scene (`MJCFLoader.load` once per scene). The scenes
    are stepped by the caller (`step` steps them in order)."""

    def __init__(self, results: list):
        if not results:
            raise ValueError("a batch needs at least one loaded copy")
        first = results[0]
        for result in results[1:]:
            if result.path != first.path or result.model.nu != first.model.nu or result.model.nv != first.model.nv:
                raise ValueError(
                    f"a batch drives copies of one model: {result.path} ({result.model.nv} DoFs, {result.model.nu} "
                    f"actuators) is not a copy of {first.path}; load the same file once per scene"
                )
        self.results = list(results)
        self.controllers = [result.controller for result in results]
        self.batched: list[str] = []  # the stages the last `set_ctrl` ran once for every copy
        self.seen: list[int] | None = None  # each copy's `Controller.compilations` when `alike` was decided
        self.alike = False  # every copy runs the same stages with the same laws (`plans_alike`)
        self.passes = None  # MuJoCo's momentum passes for every copy at once (`settle`; False: none exact)

    def __len__(self) -> int:
        return len(self.results)

    def commands(self, name: str, value, size: int, what: str) -> list:
        """Per copy, its row of `value` (copies x size; None: None for every copy), checked as `set_ctrl` checks
        one."""
        if value is None:
            return [None] * len(self)
        rows = np.asarray(value, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[0] != len(self):
            raise ControlError(
                f"{self.results[0].path}: {name} has shape {rows.shape}; the batch has {len(self)} copies of "
                f"{size} {what}: pass an array of shape ({len(self)}, {size})"
            )
        return [
            command_vector(result.path, f"{name}[{k}]", row, size, what)
            for k, (result, row) in enumerate(zip(self.results, rows))
        ]

    def set_ctrl(self, ctrl=None, qfrc_applied=None, advance: bool = True) -> None:
        """Each copy's `set_ctrl` with its row of `ctrl` (copies x nu; None: zeros) and of `qfrc_applied`
        (copies x nv; None: zeros)."""
        model = self.results[0].model
        ctrls = self.commands("ctrl", ctrl, model.nu, "actuators (nu)")
        applied = self.commands("qfrc_applied", qfrc_applied, model.nv, "DoFs (nv)")
        self.settle()
        steps = [c.begin(u, f, advance) for c, u, f in zip(self.controllers, ctrls, applied)]
        compilations = [c.compilations for c in self.controllers]
        if compilations != self.seen:  # a copy compiled again (an edit, a term switched): compare the plans
            self.seen, self.alike = compilations, self.plans_alike()
        running = [c.running for c in self.controllers]
        kept = [k for k, step in enumerate(steps) if step is not None]
        whole = any(c.whole is not None for c in self.controllers)  # MuJoCo's own step: one call per copy anyway
        if len(kept) < len(self) or not self.alike or whole:  # a copy not finite, or edited apart from the others
            self.batched = []
            for k in kept:
                self.controllers[k].run(steps[k])
            return
        stacked, self.batched = stack(steps), []
        for stage, term in enumerate(running[0]):
            terms = [copy[stage] for copy in running]
            if term.batch(stacked, steps, terms):
                self.batched.append(term.name)
            else:
                for copy, step in zip(terms, steps):
                    step.regular = stacked.regular
                    copy.contribute(step)
                stacked.regular = all(step.regular for step in steps)

    def settle(self) -> None:
        """Every copy's floating roots after the last physics step, MuJoCo's passes run once for all copies
        (`momentum.settle_copies`), where every copy's momentum term is on, has the first's roots and no free
        joint law; otherwise each copy's `begin` settles its own."""
        terms = [c.term("momentum", on=True) for c in self.controllers]
        if len(self) < 2 or any(t is None or t.law is not None for t in terms):
            return
        roots = [(r.articulation, r.body, r.qposadr, r.dofadr) for r in terms[0].roots]
        if any([(r.articulation, r.body, r.qposadr, r.dofadr) for r in t.roots] != roots for t in terms[1:]):
            return
        if self.passes is None:
            self.passes = stacked_passes(terms[0], len(self)) or False  # False: the stack is not exact
        if self.passes:
            settle_copies(
                terms,
                self.passes,
                [c.articulations for c in self.controllers],
                [c.wrenches() for c in self.controllers],
            )

    def plans_alike(self) -> bool:
        """Whether every copy runs the stages of the first with its drive laws, actuators and timestep: what the
        stages run once for all copies read from the first copy's terms."""
        first = self.controllers[0]
        names, laws, actuators = [t.name for t in first.running], first.drive_laws(), first.term("actuators")
        return all(
            [t.name for t in c.running] == names
            and c.drive_laws() == laws
            and c.timestep == first.timestep
            and (c.term("actuators") is None) == (actuators is None)
            and (actuators is None or c.term("actuators").actuators == actuators.actuators)
            for c in self.controllers[1:]
        )

    def step(self, ctrl=None, qfrc_applied=None) -> None:
        """`set_ctrl`, then one physics step of every copy's scene."""
        self.set_ctrl(ctrl, qfrc_applied)
        for result in self.results:
            result.scene.step()


def stack(steps: list[Step]) -> Step:
    """The copies' records on a leading axis; each copy's record then holds views of its rows, so a stage that
    runs per copy and one that runs for all read and write the same arrays."""
    first = steps[0]
    q, v, force = (np.stack([getattr(s, name) for s in steps]) for name in ("q", "v", "force"))
    law = np.stack([s.law for s in steps], axis=1)
    inputs, ctrl = np.stack([s.inputs for s in steps]), np.stack([s.ctrl for s in steps])
    for k, step in enumerate(steps):
        step.q, step.v, step.force, step.law, step.inputs, step.ctrl = (
            q[k],
            v[k],
            force[k],
            law[:, k],
            inputs[k],
            ctrl[k],
        )
    return Step(
        [],
        [],
        first.layout,
        q,
        v,
        force,
        law,
        inputs,
        ctrl,
        None,
        None,
        first.actuated,
        first.timestep,
        first.explicit_kv,
        first.advance,
    )
