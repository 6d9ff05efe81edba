"""MuJoCo queries both halves of the loader use: element names, the model's flags, a forward pass at a
configuration, the joint-space inverse inertia. Every number the loader maps comes from the compiled model
through these (or directly from `MjModel` arrays); nothing here re-implements MJCF semantics."""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar

import mujoco
import numpy as np

_OBJECT = {
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "joint": mujoco.mjtObj.mjOBJ_JOINT,
    "geom": mujoco.mjtObj.mjOBJ_GEOM,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "tendon": mujoco.mjtObj.mjOBJ_TENDON,
    "equality": mujoco.mjtObj.mjOBJ_EQUALITY,
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "camera": mujoco.mjtObj.mjOBJ_CAMERA,
    "texture": mujoco.mjtObj.mjOBJ_TEXTURE,
    "pair": mujoco.mjtObj.mjOBJ_PAIR,
}
_DISABLE_BITS = {name[len("mjDSBL_") :].lower(): int(bit) for name, bit in mujoco.mjtDisableBit.__members__.items()}
MJMINVAL = 1e-15  # MuJoCo's mjMINVAL: the smallest mass, time constant or length its formulas divide by


def name(model: mujoco.MjModel, kind: str, index: int) -> str:
    """The element's name, or `<kind><index>` for an unnamed one (how every note and error names it)."""
    return mujoco.mj_id2name(model, _OBJECT[kind], int(index)) or f"{kind}{index}"


UNNAMED_MODEL = "MuJoCo Model"  # the name MuJoCo gives a document without <mujoco model="...">


def model_name(model: mujoco.MjModel) -> str | None:
    """`<mujoco model="...">`, or None where the document names none."""
    names = bytes(model.names)
    own = names[: names.find(b"\0")].decode("utf-8", "replace")
    return own if own and own != UNNAMED_MODEL else None


def disabled(model: mujoco.MjModel, *flags: str) -> bool:
    """Whether any of `<flag NAME="disable"/>` is set (`"limit"`, `"constraint"`, `"spring"`, ...)."""
    return disabled_bits(int(model.opt.disableflags), *flags)


def disabled_bits(disableflags: int, *flags: str) -> bool:
    """Whether `disableflags` (MuJoCo's bits) has any of the named flags set."""
    return any(disableflags & _DISABLE_BITS[flag] for flag in flags)


def gravity(model: mujoco.MjModel) -> np.ndarray:
    """MuJoCo's gravity, zero where `<flag gravity="disable"/>` is set (a copy)."""
    return np.zeros(3) if disabled(model, "gravity") else np.array(model.opt.gravity, np.float64)


EULER_LIKE = (int(mujoco.mjtIntegrator.mjINT_EULER), int(mujoco.mjtIntegrator.mjINT_RK4))  # RK4: simulated as Euler


def explicit_damping(model: mujoco.MjModel) -> bool:
    """Whether MuJoCo takes joint damping explicitly: Euler with `eulerdamp` disabled (and RK4, which the loader
    simulates as Euler). Euler otherwise and the implicit integrators take it implicitly
    (tests/test_loader_mujoco_step.py::test_rk4_without_eulerdamp_damps_explicitly_under_either_law)."""
    return int(model.opt.integrator) in EULER_LIKE and disabled(model, "eulerdamp")


_AT_QPOS0: ContextVar[tuple[mujoco.MjModel, mujoco.MjData] | None] = ContextVar("at_qpos0", default=None)


@contextmanager
def sharing_qpos0(model: mujoco.MjModel, data: mujoco.MjData):
    """Inside the block, `forward_at(model)` at qpos0 is `data`, MuJoCo's forward pass there, made once: a load
    asks for it from several stages (body poses, the inertia, drives, solver iterations), and every one of them
    only reads it."""
    token = _AT_QPOS0.set((model, data))
    try:
        yield data
    finally:
        _AT_QPOS0.reset(token)


def forward_at(
    model: mujoco.MjModel, qpos: np.ndarray | None = None, all_equalities: bool = False, kinematics_only: bool = False
) -> mujoco.MjData:
    """MuJoCo's forward pass at qpos0 (or `qpos`): inertia and constraint rows. `all_equalities`: every equality
    active (their rows at load time, whatever `eq_active0` says); `kinematics_only`: body poses only (the full pass
    where one is shared: its poses are the same numbers). A caller reads the result and never writes it."""
    all_equalities = all_equalities and not model.eq_active0.all()  # every one on at qpos0 already: the same pass
    shared = _AT_QPOS0.get()
    if qpos is None and not all_equalities and shared is not None and shared[0] is model:
        return shared[1]
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0 if qpos is None else qpos
    if all_equalities:
        data.eq_active[:] = 1
    (mujoco.mj_kinematics if kinematics_only else mujoco.mj_forward)(model, data)
    return data


def body_mask(model: mujoco.MjModel, bodies) -> np.ndarray:
    """Per body of the model, whether it is one of `bodies` (ids): a lookup table, where `np.isin` sorts."""
    mask = np.zeros(model.nbody, dtype=bool)
    mask[list(bodies)] = True
    return mask


def inertia_blocks(model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[np.ndarray, np.ndarray]]:
    """The joint-space inertia at `data`'s state as its diagonal blocks, one per kinematic tree: (the tree's DoFs,
    its dense block), read from MuJoCo's sparse rows (data.M), so that a model of thousands of trees never builds
    an nv x nv matrix (tests/test_loader_structure.py::test_inertia_blocks_are_mujocos_full_matrix)."""
    nnz, tree_of = model.M_rownnz, model.dof_treeid
    row = np.repeat(np.arange(model.nv), nnz)  # every stored entry: its row, column and value
    entry = np.repeat(model.M_rowadr - np.cumsum(nnz) + nnz, nnz) + np.arange(int(nnz.sum()))
    col, value = model.M_colind[entry], data.M[entry]
    by_dof = np.argsort(tree_of, kind="stable")  # the DoFs, tree by tree, each tree's in order
    dof_bounds = np.searchsorted(tree_of[by_dof], np.arange(model.ntree + 1))
    by_entry = np.argsort(tree_of[row], kind="stable")
    entry_bounds = np.searchsorted(tree_of[row][by_entry], np.arange(model.ntree + 1))
    local = np.zeros(model.nv, dtype=np.int64)  # a DoF's place in its tree's block
    blocks = []
    for tree in range(model.ntree):
        dofs = by_dof[dof_bounds[tree] : dof_bounds[tree + 1]]
        local[dofs] = np.arange(len(dofs))
        mine = by_entry[entry_bounds[tree] : entry_bounds[tree + 1]]
        i, j = local[row[mine]], local[col[mine]]
        block = np.zeros((len(dofs), len(dofs)))
        block[i, j] = value[mine]
        block[j, i] = value[mine]
        blocks.append((dofs, block))
    return blocks


def inverse_inertia(model: mujoco.MjModel, data: mujoco.MjData, dofs=None) -> tuple[np.ndarray, np.ndarray]:
    """The joint-space M^-1 at `data`'s state over the trees that hold `dofs` (default: every DoF), as (those
    trees' DoFs, the inverse over them): a pseudo-inverse per tree, so that a singular M (coincident joints)
    still loads. M is block-diagonal over trees, so the blocks' inverses are M^-1's."""
    trees = set(range(model.ntree)) if dofs is None else {int(model.dof_treeid[d]) for d in dofs}
    picked = [(d, b) for d, b in inertia_blocks(model, data) if len(d) and int(model.dof_treeid[d[0]]) in trees]
    order = np.concatenate([d for d, _ in picked]) if picked else np.zeros(0, dtype=int)
    inverse = np.zeros((len(order), len(order)))
    at = 0
    for d, block in picked:
        inverse[at : at + len(d), at : at + len(d)] = np.linalg.pinv(block, hermitian=True)
        at += len(d)
    return order, inverse


def tendon_dofs(model: mujoco.MjModel, tendon: int) -> set[int]:
    """The DoFs a tendon's length can depend on: the columns of its row of MuJoCo's sparse Jacobian, a pattern the
    compiled model fixes (its joints' for a fixed tendon, those moving its path's sites and geoms otherwise)."""
    start = int(model.ten_J_rowadr[tendon])
    return {int(d) for d in model.ten_J_colind[start : start + int(model.ten_J_rownnz[tendon])]}


def tendon_passive(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Every tendon's stiffness and damping as MuJoCo applies them: zero where `<flag spring/damper="disable">`."""
    return (
        model.tendon_stiffness * (not disabled(model, "spring")),
        model.tendon_damping * (not disabled(model, "damper")),
    )


def body_dofs(model: mujoco.MjModel, body: int) -> set[int]:
    """The DoFs that move a body: its joints' and every ancestor's (none for a body fixed to the world)."""
    dofs = set()
    while body > 0:  # a body's DoFs are contiguous in MuJoCo's layout
        start = int(model.body_dofadr[body])
        dofs.update(range(start, start + int(model.body_dofnum[body])))
        body = int(model.body_parentid[body])
    return dofs


def joint_dof_count(model: mujoco.MjModel, joint: int) -> int:
    """A joint's DoFs: 6 for a free joint, 3 for a ball, 1 for a hinge or slide."""
    return {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}.get(int(model.jnt_type[joint]), 1)


def excluded_body_pairs(model: mujoco.MjModel) -> set[tuple[int, int]]:
    """The body pairs `<exclude>` takes out of MuJoCo's collision, each as (lower id, higher id)."""
    return {(s >> 16, s & 0xFFFF) for s in (int(x) for x in model.exclude_signature)}


def mujoco_filters(
    model: mujoco.MjModel, b1: int, b2: int, excluded: set[tuple[int, int]], filter_parent: bool
) -> bool:
    """True when MuJoCo never generates a contact between bodies b1 and b2 (`filter_parent`: the model does not
    disable its parent filter; `excluded`: `excluded_body_pairs`)."""
    return bool(filtered_pairs(model, np.array([b1, b2]), excluded, filter_parent)[0, 1])


def filtered_pairs(
    model: mujoco.MjModel, bodies: np.ndarray, excluded: set[tuple[int, int]], filter_parent: bool
) -> np.ndarray:
    """`mujoco_filters` for every pair of `bodies` at once, as a symmetric boolean matrix: on one weld (welded
    to each other), parent and child welds (neither the world's) where the parent filter is on, or `<exclude>`d."""
    weld = model.body_weldid[bodies]
    parent = model.body_weldid[model.body_parentid[weld]]
    same = weld[:, None] == weld[None, :]
    if filter_parent:
        moving = weld != 0
        family = (weld[:, None] == parent[None, :]) | (parent[:, None] == weld[None, :])
        same |= family & moving[:, None] & moving[None, :]
    if excluded:
        where = {int(b): i for i, b in enumerate(bodies.tolist())}
        for a, b in excluded:
            if a in where and b in where:
                same[where[a], where[b]] = same[where[b], where[a]] = True
    return same


def contact_partners(model: mujoco.MjModel, body: int) -> set[int]:
    """The bodies MuJoCo's collision can pair with `body`'s geoms: those with a geom whose contype/conaffinity bits
    meet one of the body's geoms' and which its filters let through (`mujoco_filters`: one weld, parent and child,
    `<exclude>`), and those holding the other geom of an explicit `<pair>` with one of the body's geoms; none where
    the model disables contacts."""
    if disabled(model, "contact"):
        return set()
    contype, conaffinity, owner = model.geom_contype, model.geom_conaffinity, model.geom_bodyid
    excluded, filter_parent = excluded_body_pairs(model), not disabled(model, "filterparent")
    partners = set()
    for g in np.flatnonzero(owner == body).tolist():
        meets = ((contype[g] & conaffinity) != 0) | ((contype & conaffinity[g]) != 0)
        for other in np.unique(owner[meets]).tolist():
            if not mujoco_filters(model, body, other, excluded, filter_parent):
                partners.add(other)
    for g1, g2 in zip(model.pair_geom1.tolist(), model.pair_geom2.tolist()):
        b1, b2 = int(owner[g1]), int(owner[g2])
        if body in (b1, b2):
            partners.add(b2 if b1 == body else b1)
    return partners


def transmission_dofs(model: mujoco.MjModel, actuator: int) -> set[int]:
    """The DoFs an actuator's transmission can move: those moving its site (and its reference or slider site:
    `body_dofs`), its joint's own, its tendon's (`tendon_dofs`), or for a body transmission those moving the body
    and any body it can touch. MuJoCo's body moment is the contacts' normal Jacobians, each over the DoFs moving
    either body of its contact; which geoms touch is known only at a pose, so the plan takes every body MuJoCo's
    collision can pair with the body's geoms (`contact_partners`), a superset of the DoFs any pose's moment has
    (tests/test_loader_transmissions.py::test_a_body_moment_is_mujocos_forward_pass_at_every_pose)."""
    trn, (first, second) = int(model.actuator_trntype[actuator]), (int(i) for i in model.actuator_trnid[actuator])
    if trn == int(mujoco.mjtTrn.mjTRN_TENDON):
        return tendon_dofs(model, first)
    if trn == int(mujoco.mjtTrn.mjTRN_BODY):
        return body_dofs(model, first).union(*(body_dofs(model, b) for b in contact_partners(model, first)))
    if trn in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
        start = int(model.jnt_dofadr[first])
        return set(range(start, start + joint_dof_count(model, first)))
    sites = [first] + ([second] if second >= 0 else [])
    return set().union(*(body_dofs(model, int(model.site_bodyid[s])) for s in sites))


def fixed_tendon_terms(model: mujoco.MjModel, tendon: int) -> list[tuple[int, float]]:
    """(MuJoCo joint id, coefficient) pairs of a fixed tendon, or [] for a spatial one."""
    start, count = int(model.tendon_adr[tendon]), int(model.tendon_num[tendon])
    if any(int(model.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT) for w in range(start, start + count)):
        return []
    return [(int(model.wrap_objid[w]), float(model.wrap_prm[w])) for w in range(start, start + count)]


def is_spatial(model: mujoco.MjModel, tendon: int) -> bool:
    return int(model.wrap_type[model.tendon_adr[tendon]]) != int(mujoco.mjtWrap.mjWRAP_JOINT)
