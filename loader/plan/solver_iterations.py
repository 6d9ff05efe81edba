"""PhysX solver iterations per articulation, from how strongly its joint drives couple: the Gauss-Seidel
spectral radius of the drive rows (M^-1 plus each drive's compliance), at qpos0 and the keyframes, decides how many
position iterations leave at most `RESIDUAL` of a drive impulse's error. Derivation:
docs/mapping.md#solver-iterations.
"""

from __future__ import annotations

import contextlib
import math

import mujoco
import numpy as np

from ..model import mj
from ..model.equalities import D6Joint
from ..model.mapping import Mapping

RESIDUAL = 1e-6  # the fraction of a drive impulse's error left after the sweeps
MAX_ITERATIONS = 255  # PhysX's limit for an articulation


def gauss_seidel_radius(matrix: np.ndarray) -> float:
    """Spectral radius of the Gauss-Seidel iteration matrix -(L + D)^-1 U of `matrix`."""
    if len(matrix) < 2:
        return 0.0
    lower, upper = np.tril(matrix), np.triu(matrix, 1)
    return float(np.max(np.abs(np.linalg.eigvals(-np.linalg.solve(lower, upper)))))


def sweeps_needed(radius: float, residual: float = RESIDUAL) -> int:
    if radius <= 0.0:
        return 1
    if radius >= 1.0:
        return MAX_ITERATIONS
    return min(MAX_ITERATIONS, max(1, math.ceil(math.log(residual) / math.log(radius))))


def drive_radii(
    model: mujoco.MjModel,
    weights: dict[tuple[int, int], float],
    connects: list[D6Joint],
    mapping: Mapping,
    qpos: np.ndarray | None = None,
) -> dict[int, float]:
    """Per articulation with at least two rows: the Gauss-Seidel radius of its drive rows (`weights`: per drive DoF,
    dt (D' + dt K) of the law its drive holds, `Controller.drive_weights`) and soft connect rows (the D6 joints
    `connects`) at qpos0 (or `qpos`)."""
    data = mj.forward_at(model, qpos)
    dof_of = mapping.mujoco_dofs()
    rows: dict[int, list[tuple[np.ndarray, float]]] = {}  # per articulation: (row over MuJoCo's DoFs, compliance)
    for key, weight in weights.items():
        if weight > 0 and key in dof_of:
            row = np.zeros(model.nv)
            row[dof_of[key]] = 1.0
            rows.setdefault(key[0], []).append((row, 1.0 / weight))
    for art, jacobian, compliance in connect_rows(model, data, connects):
        rows.setdefault(art, []).extend((j, compliance) for j in jacobian)
    radii = {}
    for art, entries in rows.items():
        jacobian = np.array([j for j, _ in entries])
        dofs, inverse = mj.inverse_inertia(model, data, np.flatnonzero(np.abs(jacobian).sum(axis=0)))
        jacobian = jacobian[:, dofs]
        radii[art] = gauss_seidel_radius(jacobian @ inverse @ jacobian.T + np.diag([c for _, c in entries]))
    return radii


def connect_rows(
    model: mujoco.MjModel, data: mujoco.MjData, connects: list[D6Joint]
) -> list[tuple[int, np.ndarray, float]]:
    """Per connect or weld on a D6 joint: its articulation, its three linear rows J1(p1) - J2(p2) at qpos0
    and their compliance R (PhysX's damper 1 / (dt R) leaves R per unit impulse), at a closed loop's impedance; a
    weld's three rotational rows as a second entry (a row's sign does not change the radius)."""
    result = []
    for connect in connects:
        if connect.articulation is None:
            continue
        jacobian = np.zeros((3, model.nv))
        for sign, body, anchor in (
            (1.0, connect.child_body, connect.child_anchor),
            (-1.0, connect.parent_body, connect.parent_anchor),
        ):
            point = data.xpos[body] + data.xmat[body].reshape(3, 3) @ anchor
            part = np.zeros((3, model.nv))
            mujoco.mj_jac(model, data, part, None, point, int(body))
            jacobian += sign * part
        imp = connect.row.impedance(0.0)
        result.append((connect.articulation, jacobian, connect.row.regularizer(imp, connect.diag_approx[0])))
        scale = connect.torquescale  # a weld's rotational rows: ts/2 R2^T (Jr1 - Jr2), closed
        if scale:
            rotation = np.zeros((3, model.nv))
            for sign, body in ((1.0, connect.child_body), (-1.0, connect.parent_body)):
                part = np.zeros((3, model.nv))
                mujoco.mj_jacBody(model, data, None, part, int(body))
                rotation += sign * part
            body2 = int(model.eq_obj2id[connect.equality])
            rows = 0.5 * scale * data.xmat[body2].reshape(3, 3).T @ rotation
            result.append((connect.articulation, rows, connect.row.regularizer(imp, connect.diag_approx[3])))
    return result


def largest_radii(
    model: mujoco.MjModel, weights: dict[tuple[int, int], float], connects: list[D6Joint], mapping: Mapping
) -> dict[int, float]:
    """Per articulation, the largest drive radius over qpos0 and the keyframes."""
    largest: dict[int, float] = {}
    for qpos in (None, *model.key_qpos):
        for art, radius in drive_radii(model, weights, connects, mapping, qpos).items():
            largest[art] = max(radius, largest.get(art, 0.0))
    return largest


def _blas():
    """The BLAS libraries loaded (numpy's, loaded before the loader), found once per process, through threadpoolctl
    where it is installed (the `harness` extra; the loader's own install does without it)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


_BLAS = _blas()


def one_blas_thread():
    """A block in which numpy's BLAS runs on one thread. The radii's matrices are a tree's DoFs wide: a threaded
    BLAS on busy shared cores waits for its other threads far longer than it computes, and one thread gives the
    same numbers (tests/test_loader_solver.py::test_the_radii_run_on_one_blas_thread). Without threadpoolctl the
    BLAS keeps its threads."""
    return _BLAS.limit(limits=1, user_api="blas") if _BLAS is not None else contextlib.nullcontext()


def tune_iterations(
    articulations,
    model: mujoco.MjModel,
    weights: dict[tuple[int, int], float],
    connects: list[D6Joint],
    mapping: Mapping,
    notes,
) -> None:
    """Raise each articulation's position iterations to what its drives need (never lowers them)."""
    with one_blas_thread():
        radii = largest_radii(model, weights, connects, mapping)
    for art, radius in radii.items():
        articulation = articulations[art]
        needed = sweeps_needed(radius)
        articulation.solver_position_iterations = max(articulation.solver_position_iterations, needed)
        if needed >= MAX_ITERATIONS:
            notes.approximate(
                "articulation",
                articulation.name,
                f"its drives couple so strongly (Gauss-Seidel "
                f"radius {radius:.3f}) that PhysX's {MAX_ITERATIONS} iterations leave "
                f"{radius**MAX_ITERATIONS:.1e} of the drive error",
            )
