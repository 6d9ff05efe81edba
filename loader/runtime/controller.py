"""The per-step controller: `set_ctrl` runs named terms in MuJoCo's stage order over one `Step` record.

state (`momentum`: a floating root's velocity after the last step in MuJoCo's convention; joint positions and
velocities, link velocities) -> ctrl clamp and activation -> passive forces (`tendons`)
-> `actuators` -> PhysX correction of explicit stiffness (`stiffness`) -> MuJoCo's limit and friction rows (`rows`)
-> PhysX correction of turning slides (`slides`) -> write drives and qf (`drives`) -> link forces (`fluid`,
`gravcomp`) -> equality rows (`equalities`). `without(name)` switches a term off (the public switch tests and the
isolation use); `release()` hands the joints to a caller that drives them itself. Layout: docs/architecture.md.
"""

from __future__ import annotations

from contextlib import contextmanager

import mujoco
import numpy as np

from .. import mj
from ..build.equalities import map_equalities
from ..drive import DofDrive
from .activation import MAPPED as MAPPED_DYNAMICS
from .activation import Activation
from .actuators import plan as plan_actuators
from .command import Command
from .dof_step import DofKey, DofLayout, Step, law_arrays, passive_laws
from .drive_writer import DriveWriter, dof_inertia
from .equalities import EqualityTerm
from .fluid import plan_fluid
from .gravcomp import map_gravcomp
from .momentum import plan_momentum
from .rows import plan_rows
from .slides import SlideTerm, map_slides
from .spatial_tendons import plan_paths, plan_spatial
from .state import refresh_link_velocities
from .stiffness import StiffnessTerm
from .tendons import IMPLICIT, TendonTerm, map_tendons

STAGES = ("momentum", "tendons", "actuators", "stiffness", "rows", "slides", "drives", "fluid", "gravcomp",
          "equalities")


class Controller:
    """The loaded model's per-step terms, in stage order (a term absent from a model is simply not there). The terms'
    arrays are compiled from their plans before the first `set_ctrl`, and again after `laws()` or `term()` handed
    out something a caller may edit, or a term was switched."""

    def __init__(self, model: mujoco.MjModel, mapping, articulations: list, passive: dict[DofKey, DofDrive],
                 terms: list, activation: Activation | None = None, timestep: float | None = None):
        self.model, self.mapping, self.articulations = model, mapping, articulations
        self.timestep = float(model.opt.timestep if timestep is None else timestep)  # the scene's: one PhysX step
        self.joints = [art.active_joints for art in articulations]  # the property builds a new list per call
        self.passive = passive
        self.layout = DofLayout(articulations, list(passive))
        self.activation = activation
        self.terms = sorted(terms, key=lambda term: STAGES.index(term.name))
        self.off: dict[str, object] = {}  # terms switched off, by name
        self.command = Command(model, activation)
        self.stale = True  # the terms' arrays need compiling (`compile`)
        self.base, self._readers = None, None  # the step's starting law (`compile`), link readers
        self.momentum = next((t for t in terms if t.name == "momentum"), None)  # floating roots (`settle`)

    @property
    def names(self) -> list[str]:
        return [term.name for term in self.terms]

    def term(self, name: str, on: bool = False):
        """The named term, switched on or off (`on`: only while on), or None where the model has none."""
        self.stale = True  # the caller may edit it
        found = next((t for t in self.terms if t.name == name), None)
        return found if found is not None or on else self.off.get(name)

    def laws(self) -> dict[DofKey, DofDrive]:
        """Every hinge/slide DoF's drive law with its joint actuators (what the drive carries while nothing clamps)."""
        actuators = self.term("actuators")
        return {**self.passive, **(actuators.laws if actuators is not None else {})}

    def compile(self) -> None:
        """Every term's arrays from its plan (`compile_terms`)."""
        self.base = compile_terms(self.layout, self.passive, [*self.terms, *self.off.values()])
        self.running = [term for term in self.terms if not getattr(term, "idle", False)]  # those with work
        self.stale = False

    def set_ctrl(self, ctrl, qfrc_applied: np.ndarray | None = None, advance: bool = True) -> None:
        """One step's drives and `qf` for MuJoCo's `ctrl` (None: zeros) and `qfrc_applied` (MuJoCo's layout, nv;
        None: zeros). `advance`: the first call of this physics step (activations, link forces)."""
        self.settle()
        if self.stale:
            self.compile()
        model, articulations, layout = self.model, self.articulations, self.layout
        actuated = "actuators" not in self.off
        ctrl, inputs, act = self.command(ctrl, actuated, advance)
        force = np.zeros(layout.size)
        if qfrc_applied is not None:
            applied = self.mapping.qfrc_to_sapien(qfrc_applied, articulations)
            force += np.concatenate([np.asarray(a, np.float64) for a in applied]) if applied else 0.0
        refresh_link_velocities(self.velocity_readers())
        q, v = layout.read(articulations)
        step = Step(articulations, self.joints, layout, q, v, force, self.base.copy(), inputs, ctrl, act,
                    qfrc_applied, actuated, self.timestep, int(model.opt.integrator) not in IMPLICIT, advance)
        for term in self.running:
            term.contribute(step)

    def settle(self) -> None:
        """After a physics step: floating roots' velocities as MuJoCo's step leaves them (`runtime/momentum.py`)."""
        if self.momentum is not None and "momentum" not in self.off:
            self.momentum.settle(self.articulations, [w for t in self.terms for w in getattr(t, "applied", ())])

    def forget(self) -> None:
        """A state set from outside: no step ends at it (`momentum`), MuJoCo's solve starts cold (`rows`)."""
        for term in [*self.terms, *self.off.values()]:
            getattr(term, "forget", lambda: None)()

    def contacts(self, enabled: bool) -> None:
        """SAPIEN's contacts on or off: MuJoCo solves the joint rows with its own contacts only while they are on."""
        rows = self.term("rows")
        if rows is not None:
            rows.contacts = enabled and not mj.disabled(self.model, "contact")
        if self.momentum is not None:
            self.momentum.contacts = enabled

    def velocity_readers(self) -> list:
        """The articulations whose link velocities this step's terms read (slides, fluid, connect and weld ends)."""
        self._readers = link_readers(self.terms, self.articulations) if self._readers is None else self._readers
        return self._readers

    def release(self) -> None:
        """Hand the joints to a caller that drives them itself: passive drives, own armature, PhysX's hard limits at
        MuJoCo's range, no `qf`, equalities locked; the next `set_ctrl` takes them over again."""
        timestep = self.timestep
        for term in [*self.terms, *self.off.values()]:
            if term.name == "drives":
                term.release(self.joints, self.articulations, timestep)
            elif term.name == "equalities":
                term.release(self.joints, timestep)
            elif hasattr(term, "release"):
                term.release(self.joints)

    def without(self, *names: str):
        """Switch the named terms off (a term the model lacks is already off). As a context manager, they are
        switched back on at its end. A term switched off undoes what it holds in PhysX (`removed`)."""
        unknown = [n for n in names if n not in STAGES]
        if unknown:
            raise ValueError(f"no per-step term {unknown}: the terms are {', '.join(STAGES)}")
        self.stale = True
        for term in [t for t in self.terms if t.name in names]:
            self.terms.remove(term)
            self.off[term.name] = term
            if hasattr(term, "removed"):
                term.removed(self.joints)
        self._readers = None
        return restoring(self, names)

    def restore(self, *names: str) -> None:
        """Switch the named terms (all, without names) back on; the next `set_ctrl` applies them."""
        self.stale = True
        for name in names or list(self.off):
            if name in self.off:
                self.terms.append(self.off.pop(name))
        self.terms.sort(key=lambda term: STAGES.index(term.name))
        self._readers = None


def link_readers(terms: list, articulations: list) -> list:
    """The articulations carrying a link whose velocity one of `terms` reads."""
    links = [link for t in terms if hasattr(t, "velocity_links") for link in t.velocity_links(articulations)]
    return [art for art in articulations if any(link in art.links for link in links)]


@contextmanager
def restoring(controller: Controller, names: tuple[str, ...]):
    """`without`'s context: the named terms come back on at its end."""
    try:
        yield controller
    finally:
        controller.restore(*names)


def compile_terms(layout: DofLayout, passive: dict[DofKey, DofDrive], terms: list) -> np.ndarray:
    """Every term's arrays from its plan; returns the step's starting law (`Step.law`): the passive laws, no
    via-damping force, implicit extra or offset."""
    laws = law_arrays([passive[key] for key in layout.keys])
    for term in terms:
        if term.name == "actuators":
            term.compile(layout, laws)
        elif term.name == "drives":
            term.compile(layout, offsets=any(t.name == "slides" for t in terms))
        elif hasattr(term, "compile"):
            term.compile(layout)
    return np.concatenate([laws, np.zeros((3, laws.shape[1]))])


def plan(model: mujoco.MjModel, mapping, scene, articulations: list, notes,
         timestep: float | None = None) -> tuple[Controller, list, list]:
    """Every per-step term the compiled model needs, planned once at load: (controller, actuator maps, equality
    links). The equalities' PhysX objects (fixed tendons, D6 joints) are built here too. `timestep`: the scene's
    (None: the model's), which every per-step law uses."""
    timestep = float(model.opt.timestep if timestep is None else timestep)
    passive = passive_laws(model, mapping)
    actuators, maps = plan_actuators(model, mapping, passive, notes)
    equalities = map_equalities(model, scene, articulations, mapping, notes)
    rowed = [link for link in equalities if link.kind == "MuJoCo row"]
    rows = plan_rows(model, mapping, [a for a, m in enumerate(maps) if not m.mapped], [link.index for link in rowed],
                     notes, [link.soft for link in rowed if link.soft is not None], timestep)
    activation = Activation(model, timestep=timestep) if any(int(t) in MAPPED_DYNAMICS for t in model.actuator_dyntype) else None
    tendons = map_tendons(model, mapping, notes)
    actuators.paths = paths = plan_paths(model, mapping, list(actuators.spatial_tendons.values()))
    spatial = plan_spatial(model, mapping, notes, int(model.opt.integrator) in IMPLICIT, paths)
    fluid = plan_fluid(model, mapping, notes)
    gravcomp = map_gravcomp(model, mapping, articulations, notes)
    slides = map_slides(articulations)
    connects = [link.soft for link in equalities if link.soft is not None and link.kind == "D6 joint"]
    terms = [actuators, StiffnessTerm(mj.explicit_damping(model)), DriveWriter(passive, dof_inertia(model, mapping))]
    terms += [TendonTerm(tendons, spatial)] if tendons or spatial is not None else []
    terms += [rows] if rows is not None else []
    terms += [SlideTerm(slides)] if slides else []
    terms += [term for term in (fluid, gravcomp) if term is not None]
    terms += [EqualityTerm(connects)] if connects else []
    momentum = plan_momentum(model, mapping, articulations, timestep, notes, scene)
    terms += [momentum] if momentum is not None else []
    return Controller(model, mapping, articulations, passive, terms, activation, timestep), maps, equalities
