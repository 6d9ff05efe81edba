"""MuJoCo's joint limit, frictionloss and joint-coupling rows, solved by MuJoCo at SAPIEN's state and applied as
joint forces.

MuJoCo computes its constraint force from the state at the start of a step and applies it like any other force;
its implicit integrators then treat only damping implicitly, which PhysX's drives already do. So the force MuJoCo's
own solver returns for SAPIEN's state (a copy of the model, `mj_forward`) is the force MuJoCo would apply: every
limit and friction row solved together, with the joint-space inertia, whatever else the joint carries. PhysX's hard
limit is moved out of the rows' way while `set_ctrl` runs. The contacts between the model's own shapes are MuJoCo's
too by default (`OwnContacts`): the copy's contact rows are applied with the rest, PhysX's between those shapes off.
Derivation: docs/mapping.md#joint-limits, docs/mapping.md#contacts-as-rows.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..model import mj
from ..model.frames import euler_xyz_rate_matrix
from ..model.joints import closed_range, is_limited
from ..model.mapping import Mapping
from ..model.options import MAX_DEPENETRATION_VELOCITY
from .contacts import OwnContacts
from .dof_step import DofKey, Step
from .integrated import RootPush, accelerated, integrated_force
from .term import Compilation, Handover, Term

HINGE_MARGIN = 20 * math.pi  # PhysX's hard limit sits ten turns beyond MuJoCo's ends (or the range, if wider):
SLIDE_MARGIN = 10.0  # ... and 10 m beyond a slide's; MuJoCo's soft limit has no hard stop, an impact may spin past
MAPPED_JOINTS = ("hinge", "slide")
# a free joint's frictionloss force goes on its root link (`RootPush`), a ball joint's on its angle rates (E^T tau)
FRICTIONAL_JOINTS = (*MAPPED_JOINTS, "free", "ball")
JOINT_ROWS = tuple(
    int(getattr(mujoco.mjtConstraint, f"mjCNSTR_{name}"))
    for name in ("LIMIT_JOINT", "FRICTION_DOF", "LIMIT_TENDON", "FRICTION_TENDON", "EQUALITY")
)  # the copy's equality rows: joint and tendon couplings
ACTUATION_OFF, CONTACT_OFF = int(mujoco.mjtDisableBit.mjDSBL_ACTUATION), int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
NO_STAGE = int(mujoco.mjtStage.mjSTAGE_NONE)  # a forward pass from the positions on (`solve`)
JOINT_ROW = np.isin(np.arange(len(mujoco.mjtConstraint.__members__)), JOINT_ROWS)  # per row type: a joint-space row


@dataclass(frozen=True)
class HardLimit:
    """A limited hinge/slide DoF: MuJoCo's range (an end may be open, `inf`) and the wider one PhysX keeps while the
    rows run."""

    key: DofKey
    lower: float
    upper: float
    slide: bool
    mujoco_margin: float = 0.0  # MuJoCo's jnt_margin: its limit row exists within this distance of an end

    @property
    def held(self) -> tuple[float, float]:
        """MuJoCo's range as PhysX's limit holds it: an open end `OPEN_END` beyond the finite one
        (`model.joints.closed_range`)."""
        return closed_range(self.lower, self.upper)

    @property
    def margin(self) -> float:
        low, high = self.held
        return max(SLIDE_MARGIN if self.slide else HINGE_MARGIN, high - low)

    def widened(self, q: float | None = None) -> tuple[float, float]:
        """PhysX's limit while the rows run: `margin` beyond MuJoCo's ends, and beyond `q` (a joint started or
        pushed that far past an end) as well."""
        (low, high), margin = self.held, self.margin
        low, high = low - margin, high + margin
        if q is not None:
            low, high = min(low, q - margin), max(high, q + margin)
        return low, high


class LentModel:
    """MuJoCo's copy of the model for the rows, as the loaded model itself lent for each solve: the few numbers where
    the copy differs (`overrides`: (array, flat index, values); the scene's `timestep`) are written in for the solve
    and put back after it, and so are the flags the solve sets (`with lent as model:`). A real copy duplicates the
    whole model, meshes included, and costs a large part of a load; `own()` makes one (the solves use it from then
    on: a caller that edits it changes the rows alone)."""

    def __init__(self, model: mujoco.MjModel, overrides: list[tuple[str, np.ndarray, np.ndarray]], timestep: float):
        self.overrides = overrides
        self.timestep = timestep
        self.copied = False
        self.lend(model)

    def lend(self, model: mujoco.MjModel) -> None:
        """`model` as the one lent, with its options and the overridden arrays as flat views, read once: a binding's
        attribute costs as much as the arithmetic of a step's small arrays."""
        self.model, self.opt = model, model.opt
        self.views = [(getattr(model, field).reshape(-1), index, values) for field, index, values in self.overrides]

    def override(self, field: str, index: np.ndarray, values: np.ndarray) -> None:
        """One more array where the copy differs from the lent model (`values` at flat `index` of `field`)."""
        self.overrides.append((field, index, values))
        self.lend(self.model)

    def __enter__(self) -> mujoco.MjModel:
        opt = self.opt
        own = [self._swap(array, index, values) for array, index, values in self.views] if self.views else None
        self.saved = (opt.disableflags, opt.timestep, own)
        opt.timestep = self.timestep
        return self.model

    def __exit__(self, *exc) -> None:
        opt = self.opt
        opt.disableflags, opt.timestep, own = self.saved
        if own is not None:
            for (array, index, _), values in zip(self.views, own):
                self._swap(array, index, values)

    @staticmethod
    def _swap(array: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:
        """`values` written at `index` of `array` (a view: writing it writes the model); what was there returned."""
        before = array[index]
        array[index] = values
        return before

    def own(self) -> mujoco.MjModel:
        if not self.copied:
            copied = copy.deepcopy(self.model)
            for field, index, values in self.overrides:
                self._swap(getattr(copied, field).reshape(-1), index, values)
            copied.opt.timestep = self.timestep
            self.overrides, self.copied = [], True
            self.lend(copied)
        return self.model


def overrides(model: mujoco.MjModel, edits: dict[str, dict[int, float]]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The `edits` (per array, flat index: the copy's value) that change a number of `model`, bit for bit."""
    found = []
    for field, at in edits.items():
        array = getattr(model, field).reshape(-1)
        index = np.array(sorted(at), dtype=np.intp)
        values = np.array([at[i] for i in index.tolist()], dtype=array.dtype)
        own = array[index]
        differs = (own != values) | (np.signbit(own) != np.signbit(values))
        if differs.any():
            found.append((field, index[differs], values[differs]))
    return found


class RowTerm(Term):
    """Per step: SAPIEN's state, ctrl, activation and applied force into a copy of the model (`LentModel`),
    MuJoCo's constraint force out, added to the joints' forces: its joint-space rows', and its contact rows' where
    the model's own contacts are MuJoCo's (`own`), else those are PhysX's."""

    name = "rows"

    def __init__(
        self,
        lent: LentModel,
        mapping: Mapping,
        limits: list[HardLimit],
        couplings: list[int],
        standby: list | None = None,
        own: OwnContacts | None = None,
        joint_rows: bool = True,
        limits_only: bool = False,
    ):
        self.lent, model = lent, lent.model
        self.limits_only = limits_only  # the copy's only joint-space rows are joint limits (`rowless`)
        self.own = own  # the model's own contacts, MuJoCo's while set_ctrl runs (None: PhysX's)
        self.joint_rows_planned = joint_rows  # limits, frictionloss, couplings (else only the contacts)
        self._data: mujoco.MjData | None = None  # MuJoCo's data of the copy: made at first use, or handed over
        self.couplings = couplings  # the equalities MuJoCo's copy solves
        self.standby = standby or []  # the D6 joints that hold those loops after release() (runtime/equalities.py)
        self.mapping = mapping
        self.set_limits(limits)
        joints = [(j, t) for j, t in enumerate(mapping.joints) if t.kind in MAPPED_JOINTS]
        self.keys = [(t.articulation, t.dofs[0]) for _, t in joints]  # the hinge/slide DoFs the rows' force reaches
        self.mujoco_dofs = np.array([int(model.jnt_dofadr[j]) for j, _ in joints], dtype=int)
        balls = [(int(model.jnt_dofadr[j]), t) for j, t in enumerate(mapping.joints) if t.kind == "ball"]
        self.ball_keys = [[(t.articulation, d) for d in t.dofs] for _, t in balls]  # frictionloss, contacts turn them
        self.ball_dofs = [dof for dof, _ in balls]
        self.push = RootPush(model, mapping)  # a free joint's share of an unconverged solve
        self.soft = False
        self.flags = int(model.opt.disableflags)  # the model's own
        self.with_contacts = not mj.disabled(model, "contact")  # the copy's contacts are on (`contacts`)
        self.depenetration = MAX_DEPENETRATION_VELOCITY  # m/s, PhysX's push on penetrating bodies
        self.accelerated = accelerated(model)  # MuJoCo integrates the solver's qacc (`integrated.py`)

    @property
    def data(self) -> mujoco.MjData:
        """MuJoCo's data of the copy, its couplings as the model starts them; made at first use where the load
        handed none over (`spare`)."""
        if self._data is None:
            self._keep(mujoco.MjData(self.lent.model))
        return self._data

    def spare(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        """The load's own data of the copy's model, kept (reset: as a new one) where this term has made none yet:
        making one costs most of a millisecond whatever the model's size
        (tests/test_loader_structure.py::test_a_load_makes_one_mujoco_data_where_its_rows_need_one)."""
        if self._data is not None or model is not self.lent.model:
            return False
        mujoco.mj_resetData(model, data)
        self._keep(data)
        return True

    def _keep(self, data: mujoco.MjData) -> None:
        self._data = data
        self.applying = True  # its qfrc_applied may hold a force (`mirror_state` zeroes it)
        self.reset_active()

    def claim(self) -> None:
        """Before a physics step's terms add their forces (`Controller.begin`): the model's own contacts become
        MuJoCo's, at the first step `set_ctrl` begins, so a caller that never steps through it keeps PhysX's. Taking
        them steps PhysX for an instant (`contacts.warm_up`), which would spend link forces added before it."""
        if self.own is not None and self.with_contacts:
            self.own.take()

    @property
    def mujocos(self) -> bool:
        """Whether the model's own contacts are MuJoCo's now (PhysX's between its shapes off)."""
        return self.own is not None and self.own.taken

    @property
    def mirror(self) -> mujoco.MjModel:
        """MuJoCo's copy as the term's own model (`LentModel.own`)."""
        return self.lent.own()

    @property
    def applied(self) -> list:
        """This step's root wrenches, for the momentum term."""
        return self.push.applied

    def contacts(self, enabled: bool) -> None:
        """MuJoCo's contacts are solved with the rows while SAPIEN has contacts (and the model has them); turned off,
        the model's own shapes get their groups back first (the caller then zeroes them)."""
        self.with_contacts = enabled and not mj.disabled_bits(self.flags, "contact")
        if not enabled and self.own is not None:
            self.own.give_back()

    def compile(self, compilation: Compilation) -> None:
        """Joint positions (end to end) of the DoFs the rows' force reaches and of the limited ones."""
        layout = compilation.layout
        self.flat = layout.flat_of(self.keys)
        self.ball_flat = [layout.flat_of(keys) for keys in self.ball_keys]
        self.limit_flat = layout.flat_of(self.limit_keys)
        self.every_limited = bool(np.array_equal(self.limit_flat, np.arange(layout.size)))  # q is theirs as it is
        self.scalar = scalar_state(self.lent.model, self.mapping, layout)
        self.in_order = self.scalar is not None and bool((self.scalar == np.arange(layout.size)).all())

    def set_limits(self, limits: list[HardLimit]) -> None:
        """The limited DoFs whose PhysX limit the term moves out of the rows' way."""
        self.limits = limits
        self.rows = {limit.key: limit for limit in limits}  # by (articulation, SAPIEN dof)
        self.limit_keys = [limit.key for limit in limits]
        self.margins = np.array([limit.margin for limit in limits])
        self.distances = (  # MuJoCo's ends and margin, where its limit rows begin (`rowless`)
            np.array([limit.lower for limit in limits]),
            np.array([limit.upper for limit in limits]),
            np.array([limit.mujoco_margin for limit in limits]),
        )
        self.physx = np.array([limit.widened() for limit in limits]).reshape(-1, 2)  # PhysX's limits while soft
        self.near: tuple | None = None  # half a margin within them (`clear_of`); None: to compute

    def contribute(self, step: Step) -> None:
        if not self.joint_rows_planned and not (self.with_contacts and self.mujocos):
            if step.advance:
                self.push.applied.clear()  # no root wrench this step
            return  # a model whose only rows are its contacts, with none to apply
        if not self.soft:
            self.hold(step.joints, soft=True)
        self.clear_of(step)
        if self.rowless(step):
            if step.advance:
                self.push.applied.clear()
            return  # MuJoCo's copy would have no row: its constraint force is zero
        with self.lent as model:
            self.mirror_state(step)
            solve(model, self.data, self.with_contacts, step.timestep, self.depenetration, not self.mujocos)
            force = self.joint_rows()
        if not self.lent.copied:  # the runtime's model itself, at the step's state: its passes can be shared
            step.forwarded = self.data
        step.force[self.flat] += force[self.mujoco_dofs]
        for dof, flat in zip(self.ball_dofs, self.ball_flat):  # a ball joint's angle rates take E^T tau
            if force[dof : dof + 3].any():  # its frictionloss, MuJoCo's contacts
                step.force[flat] += euler_xyz_rate_matrix(step.q[flat]).T @ force[dof : dof + 3]
        if step.advance:
            self.push(self.data, force, step.layout.links)
        self.data.qacc_warmstart[:] = self.data.qacc  # MuJoCo's next solve starts from this one's acceleration

    def rowless(self, step: Step) -> bool:
        """Whether MuJoCo's copy has no constraint row at this state, so its solve would return no force: its only
        joint-space rows are joint limits, none within its margin (MuJoCo makes a limit row where the distance to
        an end is below the joint's margin), and it makes no contacts (SAPIEN's are off). Only the copy as planned:
        one a caller took to edit (`mirror`) is solved every step
        (tests/test_loader_limit.py::test_a_joint_clear_of_its_limits_skips_the_solve)."""
        if not self.limits_only or self.lent.copied or self.with_contacts:
            return False
        q = step.q[self.limit_flat]
        lower, upper, margin = self.distances
        return bool(((q - lower >= margin) & (upper - q >= margin)).all())

    def joint_rows(self, accelerated: bool | None = None) -> np.ndarray:
        """The force of the rows SAPIEN takes from MuJoCo, as MuJoCo's step integrates it (`integrated.py`;
        `accelerated`: whether that step integrates the solver's qacc, by default as the model's integrator does):
        every row where the model's own contacts are MuJoCo's or the solve made no contact, else the joint-space
        rows alone (the contact rows, solved with them, are PhysX's to apply)."""
        data = self.data
        rows = JOINT_ROW[data.efc_type[: data.nefc]] if self.contact_rows else None
        accelerated = self.accelerated if accelerated is None else accelerated
        return integrated_force(self.lent.model, self.data, rows, accelerated)

    @property
    def contact_rows(self) -> bool:
        """Whether the copy's last solve holds contact rows that PhysX applies (the model's own contacts are not
        MuJoCo's), which the force SAPIEN takes leaves out; without a contact, every row is a joint-space row."""
        return bool(self.data.ncon) and not self.mujocos

    def solve_flags(self, actuated: bool) -> int:
        """The copy's disable flags for a solve: the model's own, actuation off while the loader's actuators are,
        contacts off while SAPIEN's are."""
        flags = self.flags if actuated else self.flags | ACTUATION_OFF
        return flags if self.with_contacts else flags | CONTACT_OFF

    def mirror_state(self, step: Step) -> None:
        """MuJoCo's copy at this step's start: SAPIEN's state, the clamped ctrl, the activation, the applied force,
        and actuation off while the loader's actuators are."""
        data = self.data
        self.lent.opt.disableflags = self.solve_flags(step.actuated)
        if self.in_order:  # SAPIEN's DoFs are MuJoCo's hinges and slides, in order
            data.qpos[:], data.qvel[:] = step.q, step.v
        elif self.scalar is not None:  # hinges and slides only: MuJoCo's qpos and qvel are joint positions
            data.qpos[:], data.qvel[:] = step.q[self.scalar], step.v[self.scalar]
        else:
            data.qpos[:], data.qvel[:] = step.mujoco_state(self.mapping)
        data.ctrl[:] = step.ctrl
        if step.act is not None:
            data.act[:] = step.act
        if step.qfrc_applied is not None:
            data.qfrc_applied[:] = step.qfrc_applied
            self.applying = True
        elif self.applying:  # zero since the last step that applied a force
            data.qfrc_applied[:] = 0.0
            self.applying = False

    def forget(self) -> None:  # a state set from outside: the next solve starts cold, as in a new MjData
        self.data.qacc_warmstart[:] = 0.0

    def set_active(self, equality: int, active: bool) -> None:
        """MuJoCo's eq_active of an equality the copy solves (a coupling, a connect or weld as rows)."""
        if equality in self.couplings:
            self.data.eq_active[equality] = int(active)

    def reset_active(self) -> None:  # the copy's couplings as the model starts them (eq_active0), no other equality
        self.data.eq_active[:] = 0
        self.data.eq_active[self.couplings] = self.lent.model.eq_active0[self.couplings]

    def clear_of(self, step: Step) -> None:
        """Move PhysX's limit of a joint within half a margin of it further out, so that it never acts while the
        rows run. Most joints are far from it: where the limited joints' positions have a length within a radius that
        every clear band holds, one dot product says so
        (tests/test_loader_limit.py::test_a_joint_in_the_band_of_physx_limit_moves_it)."""
        if not self.limits:
            return
        if self.near is None:
            low, high = self.physx[:, 0] + 0.5 * self.margins, self.physx[:, 1] - 0.5 * self.margins
            middle, half = 0.5 * (low + high), 0.5 * (high - low)
            radius = float((half - np.abs(middle)).min())  # every band holds [-radius, radius]
            self.near = (middle, half, radius * radius if radius > 0 else -1.0)
        middle, half, inside = self.near
        q = step.q if self.every_limited else step.q[self.limit_flat]
        if q.dot(q) <= inside:  # every |q_i| within the radius: every limited DoF inside its band
            return
        near = np.abs(q - middle) > half
        if not near.any():
            return
        for i in near.nonzero()[0].tolist():
            art, dof = self.limits[i].key
            self.physx[i] = self.limits[i].widened(float(q[i]))
            step.joints[art][dof].set_limit(np.array([self.physx[i]], np.float32))
            self.near = None

    def hold(self, joints, soft: bool) -> None:
        """PhysX's hard limits: widened out of the rows' way (`soft`), or at MuJoCo's range (for callers that do not
        call `set_ctrl`, and while the term is switched off)."""
        for i, limit in enumerate(self.limits):
            art, dof = limit.key
            self.physx[i] = limit.widened()
            self.near = None
            low, high = self.physx[i] if soft else limit.held
            joints[art][dof].set_limit(np.array([[low, high]], np.float32))
        if not soft and self.own is not None:
            self.own.give_back()
        for loop in self.standby:
            if soft:
                loop.stand_by()
            else:
                loop.lock(self.lent.timestep)
        self.soft = soft

    def release(self, handover: Handover) -> None:
        """PhysX's limits at MuJoCo's range; the loops' D6 joints locked."""
        self.hold(handover.joints, soft=False)

    def removed(self, joints: list[list]) -> None:
        self.hold(joints, soft=False)


def solve(
    mirror: mujoco.MjModel, data: mujoco.MjData, contacts: bool, timestep: float, depenetration: float, physx: bool
) -> None:
    """MuJoCo's solve of the copy at `data`'s state; where PhysX applies the contacts (`physx`), again without them
    while one is too deep for PhysX's push (`deep_contact`). Its forward pass leaves the sensors out: no force reads
    them, and a model's ray casts and touch sensors can cost more than the rest of the pass."""
    mujoco.mj_forwardSkip(mirror, data, NO_STAGE, 1)
    if contacts and physx and deep_contact(data, timestep, depenetration):
        mirror.opt.disableflags |= CONTACT_OFF
        mujoco.mj_forwardSkip(mirror, data, NO_STAGE, 1)
        mirror.opt.disableflags &= ~CONTACT_OFF


def scalar_state(model: mujoco.MjModel, mapping: Mapping, layout) -> np.ndarray | None:
    """Where each MuJoCo qpos (and qvel: the same addresses) sits among the joint positions end to end, for a model
    whose every joint is a mapped hinge or slide (None otherwise: `Mapping.get_state` converts free and ball
    joints)."""
    if (
        model.nq != model.nv
        or len(mapping.joints) != model.njnt
        or any(t.kind not in MAPPED_JOINTS or not t.dofs for t in mapping.joints)
    ):
        return None
    source = np.full(model.nq, -1)
    for j, target in enumerate(mapping.joints):
        source[int(model.jnt_qposadr[j])] = layout.starts[target.articulation] + target.dofs[0]
    return source if (source >= 0).all() and np.array_equal(model.jnt_qposadr, model.jnt_dofadr) else None


def deep_contact(data: mujoco.MjData, timestep: float, cap: float) -> bool:
    """A contact where PhysX and MuJoCo push differently: one so deep that MuJoCo's soft push would change its speed
    within one step by more than PhysX's depenetration cap (`cap`, m/s) lets PhysX push (dt K I depth, from MuJoCo's
    own stiffness K and impedance I of the row), or one penetrating further than PhysX resolves in a step at its cap
    (cap dt: a jammed part PhysX keeps pushing at the cap while MuJoCo holds it softly). The joint rows MuJoCo solves
    with it balance a contact force PhysX will not apply, so `RowTerm` solves them without contacts that step
    (tests/test_loader_limit.py::test_a_robot_started_deep_in_the_floor_stays_calm,
    tests/test_loader_limit.py::test_a_gripper_with_a_part_jammed_inside_another_stays_calm)."""
    if not data.ncon:
        return False
    rows = data.efc_type[: data.nefc] >= int(mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS)
    if not rows.any():
        return False
    kbip = data.efc_KBIP[: data.nefc][rows]
    depth = np.maximum(data.efc_margin[: data.nefc][rows] - data.efc_pos[: data.nefc][rows], 0.0)
    if (timestep * kbip[:, 0] * kbip[:, 2] * depth > cap).any():
        return True
    return bool((data.contact.dist[: data.ncon] < -cap * timestep).any())


def plan_rows(
    model: mujoco.MjModel,
    mapping: Mapping,
    unmapped_actuators: list[int],
    couplings: list[int],
    notes,
    standby: list | None = None,
    timestep: float | None = None,
    own: OwnContacts | None = None,
    shapeless: list[int] | None = None,
    needed: bool = False,
) -> RowTerm | None:
    """The row term for a model with limited or frictional hinge/slide joints or equalities MuJoCo's copy solves
    (`couplings`, equality ids: joint and tendon couplings, connects and welds that move only hinges, slides and free
    joints) or limited or frictional tendons, or for a model whose own contacts are MuJoCo's (`own`; None without
    any). The copy MuJoCo solves keeps only those rows and its contacts (solved while SAPIEN has contacts, applied
    where `own` holds them, else PhysX's); other equalities are D6 joints, and what the loader does not map
    (unmapped actuators, ball and free joint rows, rows of tendons that move a ball or free joint, `shapeless` geoms)
    is taken out so both sides see the same forces. `needed`: the copy even where it has no row (MuJoCo's own step
    runs on it: `mujoco_step.py`)."""
    if mj.disabled(model, "constraint") and not needed:
        return None
    limited = [
        j
        for j, t in enumerate(mapping.joints)
        if t.kind in MAPPED_JOINTS and is_limited(model, j) and not mj.disabled(model, "limit")
    ]
    frictional = [
        j
        for j, t in enumerate(mapping.joints)
        if t.kind in FRICTIONAL_JOINTS
        and np.any(model.dof_frictionloss[model.dof_jntid == j] > 0)
        and not mj.disabled(model, "frictionloss")
    ]
    couplings = [] if mj.disabled(model, "equality") else couplings
    tendons = [
        t
        for t in range(model.ntendon)
        if (model.tendon_limited[t] and not mj.disabled(model, "limit"))
        or (model.tendon_frictionloss[t] > 0 and not mj.disabled(model, "frictionloss"))
    ]
    touching = own is not None and not mj.disabled(model, "contact")
    joint_rows = bool(limited or frictional or couplings or tendons)
    if not joint_rows and not touching and not needed:
        return None
    edits: dict[str, dict[int, float]] = {}  # what MuJoCo's copy changes: per array, flat index -> value

    def edit(field: str, start: int, count: int, value: float) -> None:
        edits.setdefault(field, {}).update((i, value) for i in range(start, start + count))

    for j, target in enumerate(mapping.joints):
        if target.kind not in MAPPED_JOINTS:
            edit("jnt_limited", j, 1, 0)
        if target.kind not in FRICTIONAL_JOINTS:
            edit("dof_frictionloss", int(model.jnt_dofadr[j]), {"ball": 3}.get(target.kind, 1), 0.0)
    for t in range(model.ntendon):  # a tendon's DoFs, only where it has rows: finding them walks its path
        if (model.tendon_limited[t] or model.tendon_frictionloss[t] > 0) and not mapping.joint_dofs_only(
            model, mj.tendon_dofs(model, t)
        ):
            edit("tendon_limited", t, 1, 0)
            edit("tendon_frictionloss", t, 1, 0.0)
            notes.drop(
                "tendon",
                mj.name(model, "tendon", t),
                "length limit and frictionloss not mapped: the tendon "
                "moves a ball or free joint, which takes no joint force in SAPIEN",
            )
    for g in shapeless or []:  # a geom with no shape in SAPIEN touches nothing in the copy either
        edit("geom_contype", g, 1, 0)
        edit("geom_conaffinity", g, 1, 0)
    for a in unmapped_actuators:
        for field in ("actuator_gainprm", "actuator_biasprm"):
            width = getattr(model, field).shape[1]
            edit(field, a * width, width, 0.0)
    limits = [
        HardLimit(
            (mapping.joints[j].articulation, mapping.joints[j].dofs[0]),
            *map(float, model.jnt_range[j]),
            slide=mapping.joints[j].kind == "slide",
            mujoco_margin=float(model.jnt_margin[j]),
        )
        for j in limited
    ]
    lent = LentModel(model, overrides(model, edits), float(model.opt.timestep if timestep is None else timestep))
    limits_only = not (frictional or couplings or tendons)
    return RowTerm(lent, mapping, limits, couplings, standby, own if touching else None, joint_rows, limits_only)
