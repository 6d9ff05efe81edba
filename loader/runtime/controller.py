"""The per-step controller: `set_ctrl` runs named terms in MuJoCo's stage order over one `Step` record.

state (`momentum`: a floating root's velocity after the last step in MuJoCo's convention; joint positions and
velocities, link velocities) -> ctrl clamp and activation -> passive forces (`tendons`)
-> `actuators` -> PhysX correction of explicit stiffness (`stiffness`) -> MuJoCo's limit and friction rows (`rows`)
-> PhysX correction of turning slides (`slides`) -> write drives and qf (`drives`) -> link forces (`fluid`,
`gravcomp`) -> equality rows (`equalities`). Every term keeps the contract of `term.py`; the controller calls its
hooks by name and knows nothing else of it. `without(name)` switches a term off (the public switch tests and the
isolation use); `release()` hands the joints to a caller that drives them itself. Layout: docs/architecture.md.
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager

import mujoco
import numpy as np

from ..errors import DivergenceError
from ..model.actuators import MAPPED_DYNAMICS, ActuatorMap
from ..model.drive import DofDrive
from ..model.equalities import EqualityLink
from ..model.joints import mujoco_coordinates
from ..model.options import Options
from .activation import Activation, Command
from .actuators import plan_actuators
from .contacts import OwnContacts
from .dof_step import DofKey, DofLayout, Step, clear_qf, law_arrays, passive_laws, refresh_link_velocities
from .drive_forces import DriveForces
from .drive_writer import DriveWriter, dof_inertia
from .equalities import EqualityTerm, SoftConnect, plan_equalities
from .fluid import plan_fluid
from .gravcomp import map_gravcomp
from .integrated import RootPush
from .momentum import plan_momentum
from .mujoco_step import MujocoStep, eligible
from .rows import plan_rows
from .slides import SlideTerm, map_slides
from .stiffness import StiffnessTerm
from .tendons import TendonTerm, map_tendons, plan_paths, plan_spatial
from .term import Compilation, Handover, Term
from .transmissions import plan_moments

STAGES = (
    "momentum",
    "tendons",
    "actuators",
    "stiffness",
    "rows",
    "slides",
    "drives",
    "fluid",
    "gravcomp",
    "equalities",
)


class Controller:
    """The loaded model's per-step terms, in stage order (a term absent from a model is simply not there). The terms'
    arrays are compiled from their plans before the first `set_ctrl`, and again after `edit()` handed one out or a
    term was switched. `model` is the runtime's own compiled model and `options` its snapshot: an edit of the
    user's model reaches neither (`LoadResult.replan`)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        options: Options,
        mapping,
        articulations: list,
        passive: dict[DofKey, DofDrive],
        terms: list[Term],
        activation: Activation | None = None,
        soft_joints: dict[int, SoftConnect] | None = None,
    ):
        self.stages = list(STAGES)  # this controller's order (`add` extends it)
        unknown = [term.name for term in terms if term.name not in self.stages]
        if unknown:
            raise ValueError(f"terms {unknown} have no stage: the stages are {', '.join(self.stages)}")
        self.model, self.options, self.mapping, self.articulations = model, options, mapping, articulations
        self.joints = [art.active_joints for art in articulations]  # the property builds a new list per call
        self.passive = passive
        self.layout = DofLayout(articulations, list(passive))
        self.activation = activation
        self.soft_joints = soft_joints or {}  # equality id -> its D6 joint's soft law
        self.terms = sorted(terms, key=self.order)
        self.off: dict[str, Term] = {}  # terms switched off, by name
        self.command = Command(model, options, activation)
        self.stale = True  # the terms' arrays need compiling (`compile`)
        self.base: np.ndarray | None = None  # the step's starting law (`compile`)
        self.running: list[Term] = []  # the terms with work (`compile`)
        self.settlers: list[Term] = []  # the terms with a `settle` (`compile`)
        self.readers: list | None = None  # the articulations whose link velocities the terms read
        self.steps = 0  # physics steps begun by `set_ctrl` (its advancing calls)
        self.compilations = 0  # `compile` calls: a `Batch` compares its copies' plans again after one
        self.timings: dict[str, float] | None = None  # seconds per stage while timed (`timed`)
        self.pushed = RootPush(model, mapping)  # the caller's qfrc_applied on the floating roots, as wrenches
        self.mujoco_step = False  # asked for MuJoCo's own step as the joint forces (`use_mujoco_step`)
        self.edited = False  # a term or a law was handed out to change: MuJoCo's step would not see the change
        self.whole: MujocoStep | None = None  # `compile`'s: MuJoCo's step in place of the running terms
        self.copy_for_step = None  # () -> a rows term to run MuJoCo's step on where the model has none (`plan`)
        self.stepped_copy: Term | None = None  # that term, made at first use

    @property
    def timestep(self) -> float:
        return self.options.timestep

    @property
    def names(self) -> list[str]:
        return [term.name for term in self.terms]

    def order(self, term: Term) -> int:
        return self.stages.index(term.name)

    def add(self, term: Term, after: str) -> None:
        """A term of the caller's own (a `Term` with a new `name`), run right after the stage `after`; `without`
        and `restore` take its name like any other's. It is compiled with the others before the next
        `set_ctrl`."""
        if term.name in self.stages:
            raise ValueError(f"a term named {term.name!r} is already a stage")
        if after not in self.stages:
            raise ValueError(f"no stage {after!r}: the stages are {', '.join(self.stages)}")
        self.stages.insert(self.stages.index(after) + 1, term.name)
        self.terms.append(term)
        self.terms.sort(key=self.order)
        self.stale, self.readers = True, None

    def term(self, name: str, on: bool = False) -> Term | None:
        """The named term to read (`on`: only while switched on), or None where the model has none. To change it,
        use `edit`."""
        found = next((t for t in self.terms if t.name == name), None)
        return found if found is not None or on else self.off.get(name)

    def edit(self, name: str) -> Term | None:
        """The named term (on or off) for the caller to change its plan; the next `set_ctrl` compiles every term
        again, so the change takes effect there."""
        self.stale = self.edited = True
        return self.term(name)

    def planned(self) -> list[Term]:
        """Every term the model has, switched on or off."""
        return [*self.terms, *self.off.values()]

    def drive_laws(self) -> dict[DofKey, DofDrive]:
        """Every hinge/slide DoF's drive law with its joint actuators (what the drive carries while nothing clamps):
        the objects themselves."""
        actuators = self.term("actuators")
        return {**self.passive, **(actuators.laws if actuators is not None else {})}

    def laws(self) -> dict[DofKey, DofDrive]:
        """`drive_laws`, as copies to read."""
        return {key: DofDrive(**vars(law)) for key, law in self.drive_laws().items()}

    def edit_laws(self) -> dict[DofKey, DofDrive]:
        """`drive_laws` for the caller to change; the next `set_ctrl` compiles them."""
        self.stale = self.edited = True
        return self.drive_laws()

    def drive_weights(self) -> dict[DofKey, float]:
        """Per drive DoF, dt (D' + dt K) of the law its PhysX drive holds while nothing clamps: D' the drive's
        damping (`DofDrive.physx_damping`) with, under implicit integrators, the passive tendon dampers' and tendon
        actuators' implicit diagonal. The solver iterations read it (`plan/solver_iterations.py`)."""
        implicit, timestep = self.options.implicit, self.timestep
        actuators, tendons = self.term("actuators", on=True), self.term("tendons", on=True)
        tendon_kv = actuators.tendon_kv_diagonal() if implicit and actuators is not None else {}
        passive_diagonal = tendons.implicit_diagonal() if implicit and tendons is not None else {}
        weights = {}
        for key, law in self.drive_laws().items():
            law = DofDrive(law.stiffness, law.damping + passive_diagonal.get(key, 0.0))
            damping = law.physx_damping(timestep) + tendon_kv.get(key, 0.0)
            weights[key] = timestep * (damping + timestep * law.stiffness)
        return weights

    def compile(self) -> None:
        """Every term's arrays from its plan, and the step's starting law (`Step.law`): the passive laws, no
        via-damping force, implicit extra or offset."""
        laws = law_arrays([self.passive[key] for key in self.layout.keys])
        every = self.planned()
        compilation = Compilation(self.layout, laws, frozenset(term.name for term in every))
        self.compilation = compilation
        for term in every:
            term.compile(compilation)
        self.base = np.concatenate([laws, np.zeros((3, laws.shape[1]))])
        self.running = [term for term in self.terms if not term.idle]
        self.settlers = settling(self.terms)
        self.claimer = next((term for term in self.running if term.name == "rows" and term.own is not None), None)
        self.whole = self.whole_step() if self.mujoco_step else None
        self.stale = False
        self.compilations += 1

    def use_mujoco_step(self, on: bool = True) -> str | None:
        """`set_ctrl`'s joint forces from MuJoCo's own step at SAPIEN's state (`mujoco_step.py`) in place of the
        terms, from the next call on, or the terms again (`on` False). Returns why the terms run all the same: the
        model is not one MuJoCo's step can drive in SAPIEN's coordinates, a term other than the actuators is switched
        off or added, a term or law was handed out to change (`edit`, `edit_laws`) or the rows' copy taken
        (`mirror`); None where MuJoCo's step runs."""
        self.mujoco_step, self.stale = on, True
        if not on:
            return "switched off"
        self.compile()
        return None if self.whole is not None else self.why_not_whole()

    @contextmanager
    def on_terms(self):
        """The per-step terms give `set_ctrl`'s joint forces inside; MuJoCo's own step again after, where it ran
        before."""
        whole = self.mujoco_step
        self.use_mujoco_step(False)
        try:
            yield self
        finally:
            if whole:
                self.use_mujoco_step()

    def law(self) -> str:
        """What gives `set_ctrl`'s joint forces now: "mujoco_step", or "terms" with why MuJoCo's step does not."""
        if self.stale:
            self.compile()
        if self.stepping() is not None:
            return "mujoco_step"
        return f"terms: {self.why_not_whole() if self.mujoco_step else 'asked for (set_ctrl_law)'}"

    def implicit_laws(self) -> dict[DofKey, DofDrive]:
        """The laws whose damping MuJoCo's integrator holds implicitly this step, as the terms' drives hold it: the
        passive laws where kv is explicit (Euler) or the actuators are off, else the drive laws with their kv
        (tests/test_loader_mujoco_step.py::test_the_drives_hold_the_damping_mujoco_holds_implicitly)."""
        if "actuators" in self.off or not self.options.implicit:
            return self.passive
        return self.drive_laws()

    def rows_for_step(self):
        """The rows term MuJoCo's step runs on: the model's own (None while switched off), or a copy made for it
        where the model has no row."""
        if "rows" in self.off:
            return None
        rows = self.term("rows", on=True)
        if rows is None and self.copy_for_step is not None:
            if self.stepped_copy is None:
                self.stepped_copy = self.copy_for_step()
                self.stepped_copy.with_contacts = False  # no row to solve with them: PhysX's alone
            rows = self.stepped_copy
            rows.compile(self.compilation)
        return rows

    def why_not_whole(self) -> str:
        rows = self.term("rows") or self.rows_for_step()
        reason = eligible(self.model, rows, {term.name for term in self.planned()})
        if reason is not None:
            return reason
        if self.edited or rows.lent.copied:
            return "a term, a law or the rows' copy was handed out to change"
        return "a term is switched off or added"

    def whole_step(self) -> MujocoStep | None:
        """MuJoCo's step in place of the running terms, where it holds their law (see `use_mujoco_step`)."""
        rows, writer = self.rows_for_step(), self.term("drives", on=True)
        planned = {term.name for term in self.planned()}
        if rows is None or writer is None or eligible(self.model, rows, planned) is not None:
            return None
        if self.edited or rows.lent.copied or set(self.off) - {"actuators"} or len(self.stages) != len(STAGES):
            return None
        laws = self.implicit_laws()
        turning = {(slide.articulation, slide.dof) for slide in map_slides(self.articulations)}
        damping = [0.0 if key in turning else laws[key].damping for key in self.layout.keys]
        return MujocoStep(self.model, rows, writer, np.array(damping), self.layout)

    def set_ctrl(self, ctrl, qfrc_applied: np.ndarray | None = None, advance: bool = True) -> None:
        """One step's drives and `qf` for MuJoCo's `ctrl` (None: zeros) and `qfrc_applied` (MuJoCo's layout, nv;
        None: zeros). `advance`: the first call of this physics step (activations, link forces). On a state that is
        not finite, a call that begins a step raises DivergenceError and one that does not (a setting rewritten:
        `disable_actuators`, a cleared command) only clears `qf`; nothing else changes."""
        step = self.begin(ctrl, qfrc_applied, advance)
        if step is not None:
            self.run(step)

    def begin(self, ctrl, qfrc_applied: np.ndarray | None, advance: bool) -> Step | None:
        """`set_ctrl` up to its stages: the last step settled, the terms compiled, the state read and checked, the
        command clamped and the step's record built (None: the state is not finite and `qf` was cleared)."""
        self.settle()
        if self.stale:
            self.compile()
        articulations, layout = self.articulations, self.layout
        q, v = layout.read(articulations)
        if not finite(q, v):
            if advance:
                raise DivergenceError(self.diverged(q, v))
            clear_qf(articulations)
            return None
        self.steps += advance
        if advance and self.claimer is not None:
            self.claimer.claim()
        actuated = "actuators" not in self.off
        ctrl, inputs, act = self.command(ctrl, actuated, advance)
        if advance:
            self.push(qfrc_applied)
        whole = self.stepping()
        if whole is not None and whole.record is not None:
            return whole.record.renew(q, v, inputs, ctrl, act, qfrc_applied, actuated, advance)
        force = np.zeros(layout.size)
        if qfrc_applied is not None and whole is None:  # MuJoCo's step reads it in MuJoCo's layout
            applied = self.mapping.qfrc_to_sapien(qfrc_applied, articulations)
            force += np.concatenate([np.asarray(a, np.float64) for a in applied]) if applied else 0.0
        if whole is None:
            refresh_link_velocities(self.velocity_readers())
        step = Step(
            articulations,
            self.joints,
            layout,
            q,
            v,
            force,
            self.base.copy() if whole is None else self.base,  # MuJoCo's step writes no drive law
            inputs,
            ctrl,
            act,
            qfrc_applied,
            actuated,
            self.timestep,
            not self.options.implicit,
            advance,
        )
        if whole is not None:
            whole.record = step
        return step

    def push(self, qfrc_applied: np.ndarray | None) -> None:
        """A free joint's share of the caller's `qfrc_applied` as a wrench on its root link, once per physics step
        (tests/test_loader_free_joint.py::test_qfrc_applied_pushes_floating_roots_as_in_mujoco)."""
        if qfrc_applied is None or not self.pushed.roots:
            self.pushed.applied.clear()
        else:
            self.pushed.at_roots(qfrc_applied, self.articulations, self.layout.links)

    def stepping(self) -> MujocoStep | None:
        """MuJoCo's step where it runs in place of the terms this step (not where the rows' copy was taken since)."""
        whole = self.whole
        return whole if whole is not None and not whole.rows.lent.copied else None

    def run(self, step: Step) -> None:
        """The running terms' laws on the step, in stage order; or MuJoCo's step in their place."""
        whole = self.stepping()
        if whole is not None:
            if self.timings is None:
                whole.contribute(step)
            else:
                self.time("mujoco_step", whole.contribute, step)
            return
        if self.timings is None:
            for term in self.running:
                term.contribute(step)
        else:
            for term in self.running:
                self.time(term.name, term.contribute, step)

    def time(self, name: str, hook, *args) -> None:
        """Run a term's hook and add its seconds to `timings[name]`."""
        start = time.perf_counter()
        hook(*args)
        self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - start

    def timed(self, on: bool = True) -> dict[str, float]:
        """Time each stage's hooks (`contribute` and `settle`) from now on, into the dict returned (seconds summed
        over calls), or stop timing (`on` False). The bench reads it (`conformance/bench.py`)."""
        self.timings = {} if on else None
        return self.timings if on else {}

    def diverged(self, q: np.ndarray, v: np.ndarray) -> str:
        """The first DoF whose position or velocity is not finite, and the physics steps `set_ctrl` began."""
        i = int(np.flatnonzero(~(np.isfinite(q) & np.isfinite(v)))[0])
        a = int(np.searchsorted(self.layout.starts, i, side="right") - 1)
        joint = self.joints[a][i - self.layout.starts[a]]
        return (
            f"SAPIEN's state is not finite: joint {joint.name!r} (articulation {a}) has q = {q[i]:g}, "
            f"v = {v[i]:g} after {self.steps} physics steps under set_ctrl; the simulation diverged there "
            "(a smaller timestep, or more solver iterations, may hold it)"
        )

    def wrenches(self) -> list:
        """The link forces the terms and the caller's `qfrc_applied` added this step, (articulation, point, force,
        torque) in the world."""
        return [wrench for term in self.terms for wrench in term.applied] + self.pushed.applied

    def settle(self) -> None:
        """After a physics step: each term's `settle` (floating roots' velocities as MuJoCo's step leaves them)."""
        settlers = self.settlers if not self.stale else settling(self.terms)
        if not settlers:
            return
        wrenches = self.wrenches()
        for term in settlers:
            if self.timings is None:
                term.settle(self.articulations, wrenches)
            else:
                self.time(term.name, term.settle, self.articulations, wrenches)

    def spare(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        """Offer the planned terms a MuJoCo data of `model` that nothing else reads any more (`Term.spare`): the
        first that would make its own keeps it."""
        return any(term.spare(model, data) for term in self.planned())

    def forget(self) -> None:
        """A state set from outside: no step ends at it (`momentum`), MuJoCo's solve starts cold (`rows`)."""
        for term in self.planned():
            term.forget()

    def contacts(self, enabled: bool) -> None:
        """SAPIEN's contacts on or off: MuJoCo's copy makes its contacts (applied where the model's own contacts
        are MuJoCo's, else solved with the joint rows), and a body transmission reads them, only while they are
        on."""
        for term in self.planned():
            term.contacts(enabled)

    def velocity_readers(self) -> list:
        """The articulations whose link velocities this step's terms read (slides, connect and weld ends)."""
        if self.readers is None:
            links = [link for term in self.terms for link in term.velocity_links(self.articulations)]
            self.readers = [art for art in self.articulations if any(link in art.links for link in links)]
        return self.readers

    def release(self) -> None:
        """Hand the joints to a caller that drives them itself: passive drives, own armature, PhysX's hard limits at
        MuJoCo's range, no `qf`, equalities locked; the next `set_ctrl` takes them over again."""
        handover = Handover(self.joints, self.articulations, self.timestep)
        for term in self.planned():
            term.release(handover)
        if self.whole is not None:
            self.whole.release(handover)

    def set_equality_active(self, equality: int, active: bool) -> None:
        """MuJoCo's `data.eq_active[equality] = active`: for every term (MuJoCo's rows) and the equality's D6 joint."""
        for term in self.planned():
            term.set_active(equality, active)
        if equality in self.soft_joints:
            self.soft_joints[equality].set_active(active)

    def reset_equalities(self) -> None:
        """Every equality back to the model's `eq_active0`, as MuJoCo's mj_resetData."""
        for equality, law in self.soft_joints.items():
            law.set_active(bool(self.model.eq_active0[equality]))
        for term in self.planned():
            term.reset_active()

    def soft_joint(self, equality: int) -> SoftConnect | None:
        """The soft law of the D6 joint built for `equality` (MuJoCo's id), or None."""
        return self.soft_joints.get(equality)

    def without(self, *names: str):
        """Switch the named terms off (a term the model lacks is already off). As a context manager, they are
        switched back on at its end. A term switched off undoes what it holds in PhysX (`removed`)."""
        unknown = [n for n in names if n not in self.stages]
        if unknown:
            raise ValueError(f"no per-step term {unknown}: the terms are {', '.join(self.stages)}")
        self.stale = True
        for term in [t for t in self.terms if t.name in names]:
            self.terms.remove(term)
            self.off[term.name] = term
            term.removed(self.joints)
        self.readers = None
        return restoring(self, names)

    def restore(self, *names: str) -> None:
        """Switch the named terms (all, without names) back on; the next `set_ctrl` applies them."""
        self.stale = True
        for name in names or list(self.off):
            if name in self.off:
                self.terms.append(self.off.pop(name))
        self.terms.sort(key=self.order)
        self.readers = None


@contextmanager
def restoring(controller: Controller, names: tuple[str, ...]):
    """`without`'s context: the named terms come back on at its end."""
    try:
        yield controller
    finally:
        controller.restore(*names)


def plan(
    model: mujoco.MjModel,
    options: Options,
    mapping,
    scene,
    articulations: list,
    maps: list[tuple[ActuatorMap, list | None]],
    equalities: list[EqualityLink],
    notes,
    own: list | None = None,
    shapeless: list[int] | None = None,
) -> Controller:
    """Every per-step term the compiled model needs, planned once at load (and again at `replan`) from the
    planning half's actuator maps and equality links."""
    timestep = options.timestep
    passive = passive_laws(model, mapping)
    actuators = plan_actuators(model, mapping, passive, maps, options.implicit, notes)
    soft = plan_equalities(model, equalities, timestep)
    rowed = [link.index for link in equalities if link.kind == "MuJoCo row"]
    unmapped = [a for a, (entry, _) in enumerate(maps) if not entry.mapped]
    standby = [soft[e] for e in rowed if e in soft]
    own_contacts = OwnContacts(scene, own) if own is not None else None
    rows = plan_rows(model, mapping, unmapped, rowed, notes, standby, timestep, own_contacts, shapeless)
    dynamics = any(int(t) in MAPPED_DYNAMICS for t in model.actuator_dyntype)
    activation = Activation(model, timestep=timestep) if dynamics else None
    tendons = map_tendons(model, mapping, notes)
    actuators.paths = paths = plan_paths(model, mapping, list(actuators.spatial_tendons.values()))
    actuators.moments = plan_moments(model, mapping, actuators.moment_actuators)
    spatial = plan_spatial(model, mapping, notes, options.implicit, paths)
    fluid = plan_fluid(model, mapping, notes)
    gravcomp = map_gravcomp(model, mapping, articulations, notes)
    forces = options.tgs and mujoco_coordinates(model)  # the drives as joint forces (`drive_forces.py`)
    slides = [] if forces else map_slides(articulations)
    connects = [soft[link.index] for link in equalities if link.kind == "D6 joint"]
    writer = DriveForces(passive, model, mapping) if forces else DriveWriter(passive, dof_inertia(model, mapping))
    terms = [actuators, StiffnessTerm(options.explicit_damping), writer]
    terms += [TendonTerm(tendons, spatial)] if tendons or spatial is not None else []
    terms += [rows] if rows is not None else []
    terms += [SlideTerm(slides)] if slides else []
    terms += [term for term in (fluid, gravcomp) if term is not None]
    terms += [EqualityTerm(connects)] if connects else []
    momentum = plan_momentum(model, mapping, articulations, timestep, notes, scene)
    terms += [momentum] if momentum is not None else []
    controller = Controller(model, options, mapping, articulations, passive, terms, activation, soft)
    if rows is None:  # MuJoCo's own step needs the copy all the same
        controller.copy_for_step = lambda: plan_rows(
            model, mapping, unmapped, rowed, notes, standby, timestep, None, shapeless, needed=True
        )
    return controller


def settling(terms: list[Term]) -> list[Term]:
    """The terms whose `settle` does something after a physics step."""
    return [term for term in terms if type(term).settle is not Term.settle]


def finite(q: np.ndarray, v: np.ndarray) -> bool:
    """Whether every position and velocity is finite: one sum of squares where it is (a state of finite but huge
    numbers, whose squares overflow, is checked entry by entry)."""
    return math.isfinite(q.dot(q) + v.dot(v)) or bool(np.isfinite(q).all() and np.isfinite(v).all())
