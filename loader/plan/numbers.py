"""Compiled numbers PhysX can hold: MuJoCo accepts a NaN with a warning and a position far beyond any robot without
one, but PhysX stores poses, masses and gains in float32, so such a model would load silently wrong or fail deep
inside the mapping. Every number the loader maps is checked once, before anything is built, and the first that
cannot be held raises `MJCFError` naming the element, the field and the fix
(tests/test_loader_errors.py::test_a_compiled_number_physx_cannot_hold_is_a_typed_error_naming_the_element)."""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import MJCFError
from ..model import mj

# any other number: PhysX multiplies gains, gears, commands and inertias together in float32 (largest 3.4e38), so a
# factor beyond this overflows one step's product, far above any real robot's
# (tests/test_loader_errors.py::test_a_compiled_number_physx_cannot_hold_is_a_typed_error_naming_the_element)
MAGNITUDE = 1e15
REACH = 1e7  # m: positions and sizes beyond this are nonsense for a robot, and float32 resolves only metres there
MAX_TIMESTEP = 1.0  # s: PhysX integrates float32 states over it; no robot is simulated in steps longer than this
TURNS = 1e4  # rad: a hinge angle beyond this is held by float32 no finer than a milliradian

# (MuJoCo element kind, compiled field, a length in metres)
FIELDS = (
    ("body", "body_pos", True),
    ("body", "body_quat", False),
    ("body", "body_ipos", True),
    ("body", "body_iquat", False),
    ("body", "body_mass", False),
    ("body", "body_inertia", False),
    ("body", "body_gravcomp", False),
    ("joint", "jnt_pos", True),
    ("joint", "jnt_axis", False),
    ("joint", "jnt_stiffness", False),
    ("joint", "jnt_solref", False),
    ("joint", "jnt_solimp", False),
    ("joint", "jnt_margin", True),
    ("geom", "geom_margin", True),
    ("geom", "geom_gap", True),
    ("geom", "geom_solmix", False),
    ("site", "site_size", True),
    ("camera", "cam_pos", True),
    ("camera", "cam_fovy", False),
    ("tendon", "tendon_margin", True),
    ("tendon", "tendon_width", True),
    ("tendon", "tendon_frictionloss", False),
    ("tendon", "tendon_lengthspring", True),
    ("tendon", "tendon_solref_lim", False),
    ("tendon", "tendon_solimp_lim", False),
    ("tendon", "tendon_solref_fri", False),
    ("actuator", "actuator_actrange", False),
    ("geom", "geom_pos", True),
    ("geom", "geom_quat", False),
    ("geom", "geom_size", True),
    ("geom", "geom_friction", False),
    ("geom", "geom_solref", False),
    ("geom", "geom_solimp", False),
    ("site", "site_pos", True),
    ("site", "site_quat", False),
    ("actuator", "actuator_gear", False),
    ("actuator", "actuator_gainprm", False),
    ("actuator", "actuator_biasprm", False),
    ("actuator", "actuator_ctrlrange", False),
    ("actuator", "actuator_forcerange", False),
    ("actuator", "actuator_dynprm", False),
    ("tendon", "tendon_stiffness", False),
    ("tendon", "tendon_damping", False),
    ("tendon", "tendon_range", False),
    ("equality", "eq_data", False),
    ("equality", "eq_solref", False),
    ("equality", "eq_solimp", False),
    ("mesh", "mesh_vert", True),
)
DOF_FIELDS = ("dof_damping", "dof_armature", "dof_frictionloss")  # per DoF, named by the DoF's joint


# frames MuJoCo's kinematics rotate by their compiled quaternion as it is (a body's, composed with its parent's, is
# normalized, and set to the world's orientation when it vanishes); the compiler normalizes all but vanishing ones
FRAME_QUATS = (
    ("body", "body_quat"),
    ("inertial", "body_iquat"),
    ("geom", "geom_quat"),
    ("site", "site_quat"),
    ("camera", "cam_quat"),
)
UNIT = 1e-6  # |norm - 1| of a compiled quaternion beyond which it was left unnormalized

OPTION_FIELDS = tuple(
    name
    for name in dir(mujoco.MjOption)
    if not name.startswith("_") and isinstance(getattr(mujoco.MjOption(), name), (float, np.ndarray))
)  # real-valued options


def _held(values: np.ndarray, length: bool) -> bool:
    """Whether every number is finite and within the limit: two reductions over the array as it is stored (a NaN
    fails both comparisons), so that a model's meshes are not copied to find nothing; `_bad` then finds the row."""
    limit = REACH if length else MAGNITUDE
    return values.size == 0 or (float(np.max(values)) <= limit and float(np.min(values)) >= -limit)


def _bad(values: np.ndarray, length: bool) -> np.ndarray:
    """Rows (elements) holding a number PhysX cannot hold."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return np.zeros(len(values), dtype=bool)
    values = values.reshape(len(values), -1)
    limit = REACH if length else MAGNITUDE
    return ~np.isfinite(values).all(axis=1) | (np.abs(values) > limit).any(axis=1)


def check_numbers(model: mujoco.MjModel, path) -> None:
    """Raise `MJCFError` for the first element whose compiled numbers PhysX cannot hold, or whose name Python
    cannot read (MuJoCo keeps a name's bytes as they are; the loader names links and notes by them)."""
    _check_names(model, path)
    _check_fields(model, path)
    _check_frames(model, path)
    _check_joints(model, path)
    _check_options(model, path)


def _check_names(model: mujoco.MjModel, path) -> None:
    """Every name UTF-8 text."""
    names = bytes(model.names)
    try:
        names.decode("utf-8")
    except UnicodeDecodeError as error:
        start = names.rfind(b"\0", 0, error.start) + 1
        shown = names[start : names.find(b"\0", error.start)].decode("utf-8", "replace")
        raise MJCFError(
            path,
            f"the name {shown!r} is not UTF-8 text",
            hint="rename the element in UTF-8 text",
            rejected_by="the loader cannot read the model",
        ) from None


def _check_fields(model: mujoco.MjModel, path) -> None:
    """Every mapped array (`FIELDS`) finite and within float32's reach."""
    for kind, field, length in FIELDS:
        values = getattr(model, field)
        if not len(values) or _held(values, length):
            continue
        rows = np.flatnonzero(_bad(values, length))
        if rows.size:
            index = int(rows[0]) if kind != "mesh" else int(np.searchsorted(model.mesh_vertadr, rows[0], "right") - 1)
            _raise(path, kind, mj.name(model, kind, index), field, np.asarray(values[rows[0]]), length)


def _check_frames(model: mujoco.MjModel, path) -> None:
    """Every frame quaternion (`FRAME_QUATS`) of unit length."""
    for kind, field in FRAME_QUATS:
        values = getattr(model, field)
        rows = np.flatnonzero(np.abs(np.linalg.norm(values, axis=1) - 1.0) > UNIT) if len(values) else []
        if len(rows):
            index = int(rows[0])
            inertial = field == "body_iquat"
            label = (
                f"body '{mj.name(model, 'body', index)}' <inertial>"
                if inertial
                else f"{kind} '{mj.name(model, kind, index)}'"
            )
            raise MJCFError(
                path,
                f"{label}: {field} = {np.array2string(values[index], precision=4)} is not a unit "
                "quaternion: MuJoCo's compiler leaves a quaternion this short as written and its "
                "kinematics turn it into a degenerate rotation (a body's into the world's orientation)",
                hint=f"give {label} a quaternion of non-vanishing length (or none)",
                rejected_by="the loader cannot follow the model",
            )


def _check_joints(model: mujoco.MjModel, path) -> None:
    """Every DoF's numbers (`DOF_FIELDS`) finite, every range end a number (an infinite end leaves that side open:
    `model.joints.closed_range`) that float32 holds, every hinge's and slide's reference within PhysX's reach."""
    ranges = np.asarray(model.jnt_range, dtype=np.float64)
    bad = np.isnan(ranges).any(axis=1) | (np.isfinite(ranges) & (np.abs(ranges) > MAGNITUDE)).any(axis=1)
    if bad.any():
        joint = int(np.flatnonzero(bad)[0])
        _raise(path, "joint", mj.name(model, "joint", joint), "jnt_range", ranges[joint], False)
    for field in DOF_FIELDS:
        values = getattr(model, field)
        rows = np.flatnonzero(_bad(values, False)) if not _held(values, False) else ()
        if len(rows):
            joint = int(model.dof_jntid[rows[0]])
            _raise(path, "joint", mj.name(model, "joint", joint), field, values[rows[0]], False)
    # a hinge's or slide's reference angle or offset, where PhysX starts it
    slide = model.jnt_type == int(mujoco.mjtJoint.mjJNT_SLIDE)
    held = ~(slide | (model.jnt_type == int(mujoco.mjtJoint.mjJNT_HINGE)))
    held |= np.abs(model.qpos0[model.jnt_qposadr]) <= np.where(slide, REACH, TURNS)  # a NaN is not held
    if not held.all():
        joint = int(np.flatnonzero(~held)[0])
        _raise(
            path,
            "joint",
            mj.name(model, "joint", joint),
            "qpos0 (ref)",
            np.array([float(model.qpos0[model.jnt_qposadr[joint]])]),
            bool(slide[joint]),
            "" if slide[joint] else f"beyond {TURNS:g} rad",
        )


def _check_options(model: mujoco.MjModel, path) -> None:
    """The timestep, the solver's iterations and every real-valued option."""
    if not 0 < model.opt.timestep <= MAX_TIMESTEP:
        _raise(
            path,
            "option",
            "timestep",
            "opt.timestep",
            np.array([model.opt.timestep]),
            False,
            f"not within (0, {MAX_TIMESTEP:g}] s",
        )
    if model.opt.iterations < 1:  # MuJoCo's solver then leaves every limit, contact and equality slack
        raise MJCFError(
            path,
            f"option 'iterations' = {model.opt.iterations}: MuJoCo's constraint solver applies no "
            "constraint force (limits, contacts and equalities stay slack), which PhysX cannot follow",
            hint="give <option iterations> at least 1",
            rejected_by="the loader cannot follow the model",
        )
    options = {field: np.atleast_1d(getattr(model.opt, field)) for field in OPTION_FIELDS}
    if _held(np.concatenate(list(options.values())), False):
        return
    for field, values in options.items():  # every real-valued option: the solver's tolerances too
        if _bad(values[None, :], False).any():
            _raise(path, "option", field, f"opt.{field}", values, False)


def _raise(path, kind: str, name: str, field: str, values, length: bool, what: str = "") -> None:
    what = what or (
        "non-finite"
        if not np.isfinite(values).all()
        else (f"beyond {REACH:g} m" if length else f"beyond {MAGNITUDE:g}")
    )
    raise MJCFError(
        path,
        f"{kind} '{name}': {field} = {np.array2string(np.asarray(values), precision=4)} is {what}",
        hint=f"give {kind} '{name}' finite values{' within 1e7 m' if length else ''}: PhysX stores them in float32",
        rejected_by="PhysX cannot hold the compiled model",
    )
