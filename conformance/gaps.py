"""The known gaps between the loader and MuJoCo, each an edit of a model's `MjSpec` that takes it out on both sides
(MuJoCo compiles the edited spec and the loader loads the same one): what isolation (`isolation.py`) reruns a
failing tier without, and what the `maniskill_tensor` tier takes out of the models it judges."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from loader.model import mj
from loader.plan.joint_actuation import carried_equalities

FLAGS = mujoco.mjtDisableBit


def _zero_frictionloss(spec: mujoco.MjSpec) -> None:
    for joint in spec.joints:
        joint.frictionloss = 0.0


def _disable(bit) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        spec.option.disableflags |= int(bit)

    return edit


def _scalar_joints(model: mujoco.MjModel) -> dict[int, int]:
    """Every hinge and slide, as the joint actuation law's plan takes a robot's joints."""
    scalar = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    return {j: j for j in range(model.njnt) if int(model.jnt_type[j]) in scalar}


def _uncoupled(model: mujoco.MjModel) -> bool:
    """An active equality other than those the law carries (`carried_equalities`)."""
    if not model.neq or mj.disabled(model, "equality", "constraint"):
        return False
    return len(carried_equalities(model, _scalar_joints(model))) < int(np.count_nonzero(model.eq_active0))


def _deactivate_uncoupled(spec: mujoco.MjSpec) -> None:
    model = spec.compile()  # the equalities in the spec's order
    kept = set(carried_equalities(model, _scalar_joints(model)))
    for index, equality in enumerate(spec.equalities):
        if index not in kept:
            equality.active = False


def _no_fluid(spec: mujoco.MjSpec) -> None:
    spec.option.density = 0.0
    spec.option.viscosity = 0.0


def _no_tendon_springs(spec: mujoco.MjSpec) -> None:
    for tendon in spec.tendons:
        tendon.stiffness = np.zeros_like(tendon.stiffness)
        tendon.damping = np.zeros_like(tendon.damping)


def _half_timestep(spec: mujoco.MjSpec) -> None:
    spec.option.timestep /= 2


def _weld_free_roots(spec: mujoco.MjSpec) -> None:
    for joint in [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]:
        spec.delete(joint)
    for key in list(spec.keys):  # their qpos no longer fits the model
        spec.delete(key)


@dataclass(frozen=True)
class Gap:
    name: str
    what: str
    present: Callable[[mujoco.MjModel], bool]
    remove: Callable[[mujoco.MjSpec], None]
    automatic: bool = True  # run wherever present; otherwise only where an expectation claims it (`passes_without`)


GAPS = {
    gap.name: gap
    for gap in (
        Gap(
            "frictionloss",
            "joint frictionloss zeroed (its rows are MuJoCo's own, solved with the others)",
            lambda m: bool(m.dof_frictionloss.any()),
            _zero_frictionloss,
        ),
        Gap(
            "equality",
            "equality constraints disabled (couplings and fixed-base loops are MuJoCo's own rows; "
            "connects and welds moving a ball joint are D6 joints, coupled with joint damping)",
            lambda m: bool(m.neq and m.eq_active0.any()) and not mj.disabled(m, "equality", "constraint"),
            _disable(FLAGS.mjDSBL_EQUALITY),
        ),
        Gap(
            "uncoupled_equality",
            "equality constraints the law does not carry deactivated (welds to the world or by site, connects and "
            "welds on a floating or ball-jointed chain, couplings of spatial tendons)",
            _uncoupled,
            _deactivate_uncoupled,
            automatic=False,
        ),
        Gap(
            "limits",
            "joint limits disabled (MuJoCo's own rows on both sides, solved with MuJoCo's contacts)",
            lambda m: bool(m.jnt_limited.any()) and not mj.disabled(m, "limit", "constraint"),
            _disable(FLAGS.mjDSBL_LIMIT),
        ),
        Gap(
            "fluid",
            "fluid density and viscosity zeroed (the loader's explicit fluid forces against MuJoCo's)",
            lambda m: m.opt.density > 0 or m.opt.viscosity > 0,
            _no_fluid,
        ),
        Gap(
            "tendon_springs",
            "tendon stiffness and damping zeroed (the per-step terms carry them; the joint actuation law, fixed ones)",
            lambda m: bool(m.ntendon and (m.tendon_stiffness.any() or m.tendon_damping.any())),
            _no_tendon_springs,
            automatic=False,
        ),
        Gap(
            "free_root",
            "free joints deleted on both sides (each floating root welded where it starts, the keyframes dropped)",
            lambda m: bool((m.jnt_type == int(mujoco.mjtJoint.mjJNT_FREE)).any()),
            _weld_free_roots,
            automatic=False,
        ),
        Gap(
            "half_timestep",
            "timestep halved on both sides (integration differences shrink faster than force errors)",
            lambda m: True,
            _half_timestep,
        ),
    )
}


def present_gaps(model: mujoco.MjModel) -> list[str]:
    """The gaps run wherever the model has them (a claimed one runs too: `isolate`)."""
    return [name for name, gap in GAPS.items() if gap.automatic and gap.present(model)]


def edited_spec(path: str, gaps: tuple[str, ...]) -> mujoco.MjSpec:
    """The file's spec with `gaps` taken out."""
    return _taken_out(mujoco.MjSpec.from_file(str(path)), gaps)


def without(spec: mujoco.MjSpec, gaps: tuple[str, ...]) -> mujoco.MjSpec:
    """A copy of `spec` with `gaps` taken out."""
    return _taken_out(spec.copy(), gaps)


def _taken_out(spec: mujoco.MjSpec, gaps: tuple[str, ...]) -> mujoco.MjSpec:
    for name in gaps:
        GAPS[name].remove(spec)
    return spec
