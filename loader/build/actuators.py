"""Actuators onto PhysX joint drives and generalized forces, with `set_ctrl` to replay any MuJoCo ctrl.

An actuator on a hinge or slide joint with a fixed gain and an affine bias (motor, position, velocity and the
general PD form) is exact: its joint-space force gear*(gain*ctrl + b0) + gear^2*b1*q + gear^2*b2*qdot joins the
joint's passive spring-damper in one PhysX drive (`drive.py`). MuJoCo's implicit integrators (implicitfast, and
implicit's diagonal) treat kv implicitly, as a drive does; Euler treats it explicitly (RK4 too, which PhysX
cannot follow and is taken as Euler): there `set_ctrl` applies -kv qdot as a generalized force and leaves the
drive the joint's passive damping, with kp in the drive while that damping absorbs kp*dt (`drive.py`), else
explicit too. The integrator is read from the loaded model's `opt.integrator` on every `set_ctrl`.
An actuator on a fixed tendon applies J^T f as a generalized force, its bias evaluated from the state when
`set_ctrl` is called (call it every step); MuJoCo's implicit step holds only the diagonal of its kv J^T J (measured
exact), which joins the joints' drives, so this too is exact under implicitfast. Filter and integrator activation
dynamics are stepped by `activation.py`; muscles and site/body transmissions are not mapped.

Joint frictionloss rides on the joint's drive; the joint's own damping and gains then leave the drive as armature
and explicit forces (`friction.py`).

Force limits are exact too. MuJoCo evaluates each actuator's force at the start of the step, clamps it to its
`forcerange`, clamps the joint's sum to the joint's `actuatorfrcrange`, and then treats kv implicitly only for the
actuators its forcerange did not clamp (measured: a saturated servo's kv drops out of the step; a joint-level clamp
keeps it). On a step where a clamp binds, `set_ctrl` applies that clamped sum as a generalized force, plus
kv * qdot for the actuators still implicit, and leaves the drive with the joint's passive terms and those kv:
the step then equals MuJoCo's. Call `set_ctrl` every step for this (a drive alone clamps nothing).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import drive
from .. import mj
from ..runtime.activation import MAPPED as MAPPED_DYNAMICS
from ..runtime.activation import Activation
from ..drive import DofDrive
from ..errors import Notes
from ..runtime.fluid import Fluid
from ..runtime.friction import FrictionRow, friction_rows, note_coupled_friction
from ..runtime.gravcomp import GravityCompensation
from .joint import dof_damping, joint_stiffness
from ..runtime.limits import limit_rows
from .mapping import Mapping
from ..runtime.state import refresh_link_velocities
from ..runtime.slides import drive_offsets
from ..runtime.tendons import IMPLICIT, tendon_state
from .fixed_tendons import fixed_tendon_terms

TRN, DYN, GAIN, BIAS = mujoco.mjtTrn, mujoco.mjtDyn, mujoco.mjtGain, mujoco.mjtBias


@dataclass(frozen=True)
class ActuatorMap:
    """One MuJoCo actuator in SAPIEN. `stiffness` / `damping` are the joint-space gains it adds (gear² kp and
    gear² kv, MuJoCo's terms); the PhysX drive of a DoF sums them with the joint's passive terms and takes
    damping - stiffness x timestep as its damping (`drive.py`)."""

    name: str
    kind: str  # "motor", "position", "velocity", "general"
    joint: str | None
    tendon: str | None
    articulation: int | None
    dofs: tuple[int, ...]
    gear: float
    ctrlrange: tuple[float, float] | None
    forcerange: tuple[float, float] | None
    stiffness: float = 0.0
    damping: float = 0.0
    # MuJoCo's force law in actuator space: gain * ctrl + bias[0] + bias[1] * length + bias[2] * velocity
    gain: float = 0.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mapped: bool = True
    reason: str = ""
    dynamics: str = "none"  # "filter", "filterexact", "integrator": the gain multiplies the activation

    def unclamped(self, ctrl: float, length: float, velocity: float) -> float:
        """MuJoCo's actuator force law (before gear and before the forcerange clamp)."""
        return float(self.gain * ctrl + self.bias[0] + self.bias[1] * length + self.bias[2] * velocity)

    def force(self, ctrl: float, length: float, velocity: float) -> float:
        """The actuator force (before gear) this mapping applies, clamped to forcerange."""
        force = self.unclamped(ctrl, length, velocity)
        return min(max(force, self.forcerange[0]), self.forcerange[1]) if self.forcerange is not None else force


def _kind(model: mujoco.MjModel, a: int) -> str:
    bias = model.actuator_biasprm[a]
    if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_NONE) or not np.any(bias[:3]):
        return "motor"
    if bias[1] != 0:
        return "position"
    return "velocity" if bias[2] != 0 else "general"


@dataclass
class Actuation:
    """Everything `set_ctrl` needs: per-DoF drives, the actuators' force laws, the clamp rules."""

    model: mujoco.MjModel
    mapping: Mapping
    actuators: list[ActuatorMap]
    drives: dict[tuple[int, int], DofDrive] = field(default_factory=dict)  # (articulation, dof) -> drive
    passive: dict[tuple[int, int], DofDrive] = field(default_factory=dict)  # the same without actuators
    tendon_terms: dict[int, list[tuple[int, int, float]]] = field(default_factory=dict)  # actuator -> (a, dof, coef)
    enabled: bool = True
    # DoFs whose actuator force MuJoCo can clamp (forcerange or actuatorfrcrange) -> their joint actuators
    limited: dict[tuple[int, int], list[int]] = field(default_factory=dict)
    joint_range: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)  # actuatorfrcrange
    tendons: list = field(default_factory=list)  # passive fixed tendons (`tendon.PassiveTendon`), every step
    friction: dict[tuple[int, int], FrictionRow] = field(default_factory=dict)  # frictional hinge/slide DoFs
    limits: dict = field(default_factory=dict)  # limited hinge/slide DoFs whose soft limit rows ride on the drive
    limits_soft: bool = False  # PhysX's hard limits of those DoFs are widened out of the rows' way
    _limit_table: tuple | None = field(default=None, repr=False)  # (keys, lower + margin, upper - margin)
    armature: dict[tuple[int, int], float] = field(default_factory=dict)  # PhysX armature last set, friction DoFs
    applied: dict = field(default_factory=dict)  # per PhysX joint, the drive settings last written (`drive.apply`)
    activation: Activation | None = None  # actuators with filter / integrator dynamics (`activation.py`)
    fluid: Fluid | None = None  # MuJoCo's inertia-box fluid forces, added once per step
    gravcomp: GravityCompensation | None = None  # partial gravity compensation forces, added once per step
    connects: list = field(default_factory=list)  # connect/weld equalities' soft law (`connect.py`), per step
    slides: list = field(default_factory=list)  # prismatic DoFs on links that turn (`slide.py`), per step
    _velocity_readers: list | None = field(default=None, repr=False)  # articulations whose link velocities are read

    def set_ctrl(self, articulations, ctrl, qfrc_applied: list[np.ndarray] | None = None,
                 advance: bool = True) -> None:
        """Drive targets and `qf` for this ctrl, the passive tendons' forces, and `qfrc_applied` (per
        articulation, SAPIEN's DoF order) on top. `advance`: take the activations one step (once per step)."""
        model = self.model
        ctrl = np.zeros(model.nu) if ctrl is None else np.asarray(ctrl, dtype=np.float64).copy()
        clamp = not mj.disabled(model, "clampctrl")
        if clamp and model.nu:
            limited = model.actuator_ctrllimited.astype(bool)
            ctrl[limited] = np.clip(ctrl[limited], *model.actuator_ctrlrange[limited].T)
        clamped_ctrl = ctrl
        if self.activation is not None and self.enabled:
            ctrl = self.activation.inputs(clamped_ctrl)  # what each gain multiplies: ctrl or act
            if advance:
                self.activation.advance(clamped_ctrl)
        drives = dict(self.drives if self.enabled else self.passive)
        constants = {key: d.constant for key, d in drives.items()}
        forces = [np.zeros(art.dof) for art in articulations]
        if qfrc_applied is not None:
            forces = [f + np.asarray(applied, np.float64) for f, applied in zip(forces, qfrc_applied)]
        explicit_kv = int(model.opt.integrator) not in IMPLICIT  # Euler, RK4
        joints = [art.active_joints for art in articulations]  # the property builds a new list per call
        refresh_link_velocities(self.velocity_readers(articulations))
        if self.limits and not self.limits_soft:
            self.hold_limits(joints, soft=True)
        q = [np.asarray(art.get_qpos(), np.float64) for art in articulations]
        v = [np.asarray(art.get_qvel(), np.float64) for art in articulations]
        tendon_kv: dict[tuple[int, int], float] = {}  # implicit tendon damping and kv diagonal this step, per DoF
        for tendon in self.tendons:
            for art, dof, force, diagonal in tendon.forces(q, v, not explicit_kv):
                forces[art][dof] += force
                if diagonal:
                    tendon_kv[(art, dof)] = tendon_kv.get((art, dof), 0.0) + diagonal
        clamped: set[int] = set()  # joint actuators applied explicitly this step
        via_damping: dict[tuple[int, int], float] = {}
        if self.enabled:
            for key, members in self.limited.items():
                step = self._clamped_step(key, members, ctrl, q[key[0]][key[1]], v[key[0]][key[1]], explicit_kv)
                if step is not None:
                    drives[key], constants[key], force, via_damping[key] = step
                    forces[key[0]][key[1]] += force
                    clamped.update(members)
        for a, actuator in enumerate(self.actuators):
            if not actuator.mapped or not self.enabled or a in clamped:
                continue
            if actuator.joint is not None:
                key = (actuator.articulation, actuator.dofs[0])
                constants[key] += actuator.gear * (actuator.gain * ctrl[a] + actuator.bias[0])
                continue
            terms = self.tendon_terms[a]
            length, speed = (actuator.gear * x for x in tendon_state(terms, q, v))
            force = actuator.force(ctrl[a], length, speed)
            saturated = force != actuator.unclamped(ctrl[a], length, speed)
            implicit = 0.0 if explicit_kv else self._implicit_tendon_kv(actuator, saturated)
            for art, dof, c in terms:
                # MuJoCo's implicit step holds the diagonal of kv J^T J only: it joins the drive, and the
                # explicit force gets it back at the current rate (measured exact, as for passive tendons)
                forces[art][dof] += actuator.gear * c * force + implicit * c * c * v[art][dof]
                tendon_kv[(art, dof)] = tendon_kv.get((art, dof), 0.0) + implicit * c * c
        timestep = float(model.opt.timestep)
        self._explicit_terms(drives, constants, forces, clamped, q, v, timestep, explicit_kv, tendon_kv)
        for key, row in self.friction.items():  # the drive carries the friction (`friction.py`)
            art, dof = key
            damping = self._armature_form(key, row.armature, joints[art][dof], drives[key], constants[key], q, v,
                                          forces, tendon_kv, via_damping, timestep)
            drives[key], constants[key] = row.drive(v[art][dof], timestep, row.scale(damping, timestep))
        for key in self._near_limits(q):  # a joint at its limit: the drive carries the row (`limit.py`)
            row = self.limits[key]
            art, dof = key
            law = drives[key]
            step = row.drive(q[art][dof], v[art][dof], timestep,
                             row.scale(law.damping + tendon_kv.get(key, 0.0), timestep))
            if step is None:  # clear of its ends: the joint's own armature back, nothing to remember
                self._set_armature(joints[art][dof], key, row.armature, row.armature)
                self.armature.pop(key, None)
                continue
            self._armature_form(key, row.armature, joints[art][dof], law, constants[key], q, v, forces, tendon_kv,
                                via_damping, timestep)
            forces[art][dof] += step[2]
            drives[key], constants[key] = step[0], step[1]
        offsets = drive_offsets(self.slides, timestep)
        for (art, dof), dof_drive in drives.items():
            if tendon_kv.get((art, dof)):
                dof_drive = dataclasses.replace(dof_drive, damping=dof_drive.damping + tendon_kv[(art, dof)])
            joint = joints[art][dof]
            forces[art][dof] += drive.apply(joint, dof_drive, constants[(art, dof)], timestep,
                                            via_damping.get((art, dof), 0.0), self.applied, (art, dof),
                                            offsets.get((art, dof), 0.0))
        for art, qf in zip(articulations, forces):
            if art.dof:
                art.set_qf(qf.astype(np.float32))
        for link_forces in (self.fluid, self.gravcomp):  # link forces accumulate until the step: once per step
            if link_forces is not None and advance:
                link_forces.apply(articulations)
        for connect in self.connects:
            connect.update(timestep)

    def velocity_readers(self, articulations) -> list:
        """The articulations whose link velocities this step's terms read (slides, fluid, connect and weld ends)."""
        if self._velocity_readers is None:
            links = [s.parent for s in self.slides]
            links += [articulations[b.articulation].links[b.link] for b in (self.fluid.bodies if self.fluid else ())]
            links += [end for c in self.connects for end in (c.child, c.parent) if end is not None]
            self._velocity_readers = [art for art in articulations if any(link in art.links for link in links)]
        return self._velocity_readers

    def release(self, articulations) -> None:
        """Hand the joints to a caller that drives them itself (their own drive targets, no `set_ctrl`): every
        DoF's drive gets the joint's passive spring-damper, frictional joints their own armature back (their
        friction is then not carried), limits PhysX's hard limit at MuJoCo's range, `qf` is cleared. The next
        `set_ctrl` takes them over again."""
        joints = [art.active_joints for art in articulations]
        timestep = float(self.model.opt.timestep)
        for (art, dof), passive in self.passive.items():
            drive.apply(joints[art][dof], passive, passive.constant, timestep)
        for (art, dof), row in list(self.friction.items()) + list(self.limits.items()):
            joints[art][dof].set_armature(np.array([row.armature], np.float32))
        if self.limits:
            self.hold_limits(joints, soft=False)
        for art in articulations:
            if art.dof:
                art.set_qf(np.zeros(art.dof, np.float32))
        for connect in self.connects:
            connect.lock(timestep)
        self.applied.clear()
        self.armature.clear()

    def _armature_form(self, key, own_armature: float, joint, law: DofDrive, constant: float, q, v, forces,
                       tendon_kv, via_damping, timestep: float) -> float:
        """Free the DoF's drive for a constraint row (friction, limit): its implicit damping D becomes armature
        dt D plus the explicit force -D v, its stiffness and constant explicit forces. Returns D."""
        art, dof = key
        damping = law.damping + tendon_kv.pop(key, 0.0)
        forces[art][dof] += (constant + via_damping.pop(key, 0.0) - law.stiffness * q[art][dof]
                             - damping * v[art][dof])
        self._set_armature(joint, key, own_armature + timestep * damping)
        return damping

    def _set_armature(self, joint, key, armature: float, unset: float | None = None) -> None:
        """Write the DoF's PhysX armature when it differs from the last written (`unset`: what it is if never)."""
        if self.armature.get(key, unset) != armature:
            joint.set_armature(np.array([armature], np.float32))
            self.armature[key] = armature

    def _near_limits(self, q) -> list[tuple[int, int]]:
        """The limited DoFs to visit this step: those past an end (within its margin), and those whose armature
        still holds a row's implicit damping from an earlier step (vectorised: most joints are clear)."""
        if not self.limits:
            return []
        if self._limit_table is None:
            keys = list(self.limits)
            rows = [self.limits[k] for k in keys]
            self._limit_table = (keys, np.array([r.lower + r.margin for r in rows]),
                                 np.array([r.upper - r.margin for r in rows]))
        keys, low, high = self._limit_table
        values = np.array([q[art][dof] for art, dof in keys])
        near = (values < low) | (values > high)
        return [k for k, hit in zip(keys, near) if hit or k in self.armature]

    def hold_limits(self, joints, soft: bool) -> None:
        """PhysX's hard limit of every DoF with soft limit rows: widened out of the rows' way (`soft`), or at
        MuJoCo's range (for callers that do not call `set_ctrl`)."""
        for (art, dof), row in self.limits.items():
            low, high = row.physx_limits() if soft else (row.lower, row.upper)
            joints[art][dof].set_limit(np.array([[low, high]], np.float32))
        self.limits_soft = soft

    def _explicit_terms(self, drives, constants, forces, clamped: set[int], q, v, timestep: float,
                        explicit_kv: bool, tendon_kv: dict[tuple[int, int], float]) -> None:
        """On the DoFs of joint actuators, under Euler, their kv leaves the drive as the explicit force -kv qdot; and
        on every DoF where the damping left in the drive (with the tendons' implicit diagonal) cannot absorb the
        stiffness (kp, spring) times dt (`drive.py`), the stiffness leaves it as the explicit force (constant - K q),
        which is what MuJoCo does."""
        kv: dict[tuple[int, int], float] = {}
        for a, actuator in enumerate(self.actuators if self.enabled else ()):
            if actuator.mapped and actuator.joint is not None and a not in clamped:
                key = (actuator.articulation, actuator.dofs[0])
                kv[key] = kv.get(key, 0.0) + (actuator.damping if explicit_kv else 0.0)
        def exact(key, law: DofDrive) -> bool:
            return law.damping + tendon_kv.get(key, 0.0) - law.stiffness * timestep >= 0.0

        for key, law in drives.items():
            if key not in kv and not exact(key, law):
                kv[key] = 0.0
        for (art, dof), damping in kv.items():
            law = drives[(art, dof)]
            if damping:  # every joint actuator's kv is explicit: the drive keeps the passive damping (not a
                # difference, whose rounding would move the kp*dt boundary below)
                law = dataclasses.replace(law, damping=self.passive[(art, dof)].damping)
                forces[art][dof] -= damping * v[art][dof]
            if not exact((art, dof), law):
                forces[art][dof] += constants[(art, dof)] - law.stiffness * q[art][dof]
                constants[(art, dof)] = 0.0
                law = dataclasses.replace(law, stiffness=0.0)
            drives[(art, dof)] = law

    @staticmethod
    def _implicit_tendon_kv(actuator: ActuatorMap, saturated: bool) -> float:
        """A tendon actuator's joint-space kv (gear^2 kv) that MuJoCo's implicit step treats implicitly: none once
        its forcerange clamps it (as for joint actuators)."""
        return 0.0 if saturated else actuator.damping

    def _clamped_step(self, key, members: list[int], ctrl, q: float, v: float, explicit_kv: bool = False):
        """MuJoCo's actuator force on one DoF at the state (q, v) when a clamp binds there: (drive, constant,
        clamped actuator force, kv * qdot of the actuators MuJoCo still treats implicitly) for this step, or None
        when nothing clamps (the drive alone is exact)."""
        total, binding, implicit_kv = 0.0, False, 0.0
        for a in members:
            actuator = self.actuators[a]
            gear = actuator.gear
            force = actuator.force(ctrl[a], gear * q, gear * v)
            if force != actuator.unclamped(ctrl[a], gear * q, gear * v):
                binding = True
            elif not explicit_kv:
                implicit_kv += actuator.damping
            total += gear * force
        if key in self.joint_range:
            low, high = self.joint_range[key]
            binding = binding or not low <= total <= high
            total = min(max(total, low), high)
        if not binding:
            return None
        passive = self.passive[key]
        drive_now = DofDrive(passive.stiffness, passive.damping + implicit_kv, passive.constant)
        return drive_now, passive.constant, total, implicit_kv * v


def plan_actuation(model: mujoco.MjModel, mapping: Mapping, notes: Notes) -> Actuation:
    actuation = Actuation(model, mapping, [])
    # every hinge/slide DoF gets its passive law; actuators add to it
    for j, target in enumerate(mapping.joints):
        if target.kind in ("hinge", "slide"):
            adr = model.jnt_qposadr[j]
            stiffness = joint_stiffness(model, j)
            passive = DofDrive(stiffness, dof_damping(model, int(model.jnt_dofadr[j])),
                               stiffness * float(model.qpos_spring[adr]))
            actuation.passive[(target.articulation, target.dofs[0])] = passive
            actuation.drives[(target.articulation, target.dofs[0])] = DofDrive(**vars(passive))
    actuation.friction = friction_rows(model, mapping)
    actuation.limits = limit_rows(model, mapping, notes)
    if any(int(t) in MAPPED_DYNAMICS for t in model.actuator_dyntype):
        actuation.activation = Activation(model)
    disabled = mj.disabled(model, "actuation")
    for a in range(model.nu):
        entry = _plan_one(model, mapping, a, disabled, actuation)
        actuation.actuators.append(entry)
        if not entry.mapped:
            notes.drop("actuator", entry.name, entry.reason)
    note_coupled_friction(model, mapping, actuation, notes)
    members: dict[tuple[int, int], list[int]] = {}
    for a, entry in enumerate(actuation.actuators):
        if entry.mapped and entry.joint is not None:
            members.setdefault((entry.articulation, entry.dofs[0]), []).append(a)
    for j, target in enumerate(mapping.joints):  # <joint actuatorfrcrange>: MuJoCo clamps the joint's actuator sum
        key = (target.articulation, target.dofs[0]) if target.kind in ("hinge", "slide") else None
        if key in members and model.jnt_actfrclimited[j]:
            actuation.joint_range[key] = tuple(float(x) for x in model.jnt_actfrcrange[j])
    for key, indices in members.items():
        if key in actuation.joint_range or any(actuation.actuators[a].forcerange for a in indices):
            actuation.limited[key] = indices
    return actuation


def _plan_one(model, mapping, a, disabled, actuation) -> ActuatorMap:
    name = mj.name(model, "actuator", a)
    gear = float(model.actuator_gear[a][0])
    ctrlrange = tuple(float(x) for x in model.actuator_ctrlrange[a]) if model.actuator_ctrllimited[a] else None
    forcerange = tuple(float(x) for x in model.actuator_forcerange[a]) if model.actuator_forcelimited[a] else None
    trn = int(model.actuator_trntype[a])
    target = int(model.actuator_trnid[a][0])
    base = {"name": name, "kind": _kind(model, a), "joint": None, "tendon": None, "articulation": None, "dofs": (),
            "gear": gear, "ctrlrange": ctrlrange, "forcerange": forcerange}
    if disabled:
        return ActuatorMap(**base, mapped=False, reason="actuation disabled by the model's <flag actuation>")
    dyntype = int(model.actuator_dyntype[a])
    if dyntype != int(DYN.mjDYN_NONE) and dyntype not in MAPPED_DYNAMICS:
        dyn = DYN(dyntype).name.removeprefix("mjDYN_").lower()
        return ActuatorMap(**base, mapped=False, reason=f"activation dynamics ({dyn}) are not mapped")
    if int(model.actuator_gaintype[a]) != int(GAIN.mjGAIN_FIXED) or int(model.actuator_biastype[a]) not in (
            int(BIAS.mjBIAS_NONE), int(BIAS.mjBIAS_AFFINE)):
        return ActuatorMap(**base, mapped=False, reason="gain or bias is not affine (muscle or user)")
    bias = model.actuator_biasprm[a] if int(model.actuator_biastype[a]) == int(BIAS.mjBIAS_AFFINE) else np.zeros(3)
    base["gain"] = float(model.actuator_gainprm[a][0])
    base["dynamics"] = MAPPED_DYNAMICS.get(dyntype, "none")
    base["bias"] = (float(bias[0]), float(bias[1]), float(bias[2]))
    if trn == int(TRN.mjTRN_JOINT):
        joint = mapping.joints[target]
        if joint.kind not in ("hinge", "slide"):
            return ActuatorMap(**base, mapped=False, reason=f"drives a {joint.kind} joint")
        stiffness, damping = -bias[1] * gear**2, -bias[2] * gear**2
        key = (joint.articulation, joint.dofs[0])
        dof_drive = actuation.drives[key]
        dof_drive.stiffness += stiffness
        dof_drive.damping += damping
        base.update(joint=mj.name(model, "joint", target), articulation=joint.articulation,
                    dofs=joint.dofs)
        return ActuatorMap(**base, stiffness=float(stiffness), damping=float(damping))
    if trn == int(TRN.mjTRN_TENDON):
        terms = fixed_tendon_terms(model, target)
        if not terms:
            return ActuatorMap(**base, mapped=False, reason="drives a spatial tendon")
        mapped_terms = []
        for joint_id, coefficient in terms:
            joint = mapping.joints[joint_id]
            if joint.kind not in ("hinge", "slide"):
                return ActuatorMap(**base, mapped=False, reason="its tendon crosses a ball or free joint")
            mapped_terms.append((joint.articulation, joint.dofs[0], coefficient))
        actuation.tendon_terms[a] = mapped_terms
        base.update(tendon=mj.name(model, "tendon", target),
                    articulation=mapped_terms[0][0], dofs=tuple(d for _, d, _ in mapped_terms))
        return ActuatorMap(**base, stiffness=float(-bias[1] * gear**2), damping=float(-bias[2] * gear**2))
    kind = TRN(trn).name.removeprefix("mjTRN_").lower()
    return ActuatorMap(**base, mapped=False, reason=f"{kind} transmission is not mapped")
